"""UBX configuration messages the driver sends (built with pyubx2's generator)."""

from __future__ import annotations

UBX_NAV_PVT = (0x01, 0x07)
NMEA_IDS = {"GGA": (0xF0, 0x00), "GLL": (0xF0, 0x01), "GSA": (0xF0, 0x02),
            "GSV": (0xF0, 0x03), "RMC": (0xF0, 0x04), "VTG": (0xF0, 0x05)}
CFG_RATE = (0x06, 0x08)
CFG_MSG = (0x06, 0x01)


def cfg_rate(rate_hz: float) -> bytes:
    """CFG-RATE: measurement period in ms, one navigation solution per measurement, GPS
    time reference."""
    import pyubx2

    return pyubx2.UBXMessage("CFG", "CFG-RATE", pyubx2.SET, measRate=round(1000 / rate_hz),
                             navRate=1, timeRef=1).serialize()


def cfg_msg(msg_class: int, msg_id: int, rate: int) -> bytes:
    """CFG-MSG (short form): output ``msg_class/msg_id`` every ``rate`` solutions on the
    current port (0: off)."""
    import pyubx2

    return pyubx2.UBXMessage("CFG", "CFG-MSG", pyubx2.SET, msgClass=msg_class, msgID=msg_id,
                             rateUART1=rate).serialize()
