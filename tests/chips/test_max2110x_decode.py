"""MAX2110x tables and pure decoding against the datasheet/facts vectors (no bus, no time)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from pydantic import ValidationError

from imuhal.bus.base import Bus, BusKind
from imuhal.bus.registers import RegisterView
from imuhal_chips.max2110x import decode
from imuhal_chips.max2110x.registers import (
    ACCEL_RANGE_G,
    GYRO_RANGE_DPS,
    MAX21100,
    MAX21105,
    SPI_CONVENTION,
    acc_cfg1,
    gyro_cfg1,
    pwr_acc_cfg,
)
from imuhal_chips.max2110x.settings import Max21100Settings, Max21105Settings

VECTORS = json.loads((Path(__file__).parent.parent / "data/chips/max2110x_vectors.json")
                     .read_text())


def test_facts_example_sample_decodes_to_one_dps_and_one_g_at_500dps_4g() -> None:
    ex = VECTORS["max21105"]["example_sample"]
    data = bytes(ex["bytes_0x24_0x2F"])
    gyro = decode.words3(data, 0)
    accel = decode.words3(data, 6)
    assert list(gyro) == ex["gyro_raw"] and list(accel) == ex["accel_raw"]
    rad_s = decode.gyro_counts_to_rad_s(gyro, GYRO_RANGE_DPS[500][1])
    m_s2 = decode.accel_counts_to_m_s2(accel, ACCEL_RANGE_G[4][1])
    assert [math.degrees(v) for v in rad_s] == pytest.approx(ex["at_500dps_4g"]["gyro_dps"])
    assert [v / 9.80665 for v in m_s2] == pytest.approx(ex["at_500dps_4g"]["accel_g"])


def test_sensitivities_match_facts_and_full_scale_is_30000_counts() -> None:
    for dps, (_, lsb) in GYRO_RANGE_DPS.items():
        assert lsb == VECTORS["max21100"]["gyro_lsb_per_dps"][str(dps)]
        assert lsb * dps == 30000
    for g, (_, lsb) in ACCEL_RANGE_G.items():
        assert lsb == VECTORS["max21100"]["accel_lsb_per_g"][str(g)]
        assert lsb * g == 30000


def test_temperature_is_256_counts_per_degc_with_6400_at_25c() -> None:
    t = VECTORS["max21105"]["temp"]
    assert decode.temp_counts_to_degc(t["output_at_25C"]) == 25.0
    assert decode.temp_counts_to_degc(-256) == -1.0


def test_saturation_flagged_at_nominal_full_scale_either_sign() -> None:
    assert not decode.saturated((29999, -29999, 0))
    assert decode.saturated((30000, 0, 0))
    assert decode.saturated((0, -30000, 0))
    assert decode.saturated((0, 0, 32767))


def test_burst_layout_puts_status_first_and_temperature_last_for_both_parts() -> None:
    assert MAX21105.burst_length == 15  # 0x23..0x31
    assert MAX21100.burst_length == 21  # 0x23..0x37 (mag words in between)
    words = [100, -100, 200, -200, 7500, 0]
    body = b"".join(w.to_bytes(2, "big", signed=True) for w in words)
    for part in (MAX21105, MAX21100):
        filler = bytes(part.burst_length - 1 - len(body) - 2)
        raw = bytes([0x05]) + body + filler + (6400).to_bytes(2, "big")
        burst = decode.split_burst(raw)
        assert burst.gyro == (100, -100, 200) and burst.accel == (-200, 7500, 0)
        assert burst.temperature == 6400
        assert burst.gyro_ready and burst.accel_ready and not burst.overrun


def test_register_codes_reproduce_the_user_guide_example() -> None:
    # 0x01<-0x10 (10 Hz, 2000 dps); 0x02<-0x01 (4 kHz); 0x04<-0x40 (8 g); 0x05<-0x00
    # (2 kHz, ODR/48)
    writes = dict(VECTORS["max21105"]["user_guide_example_config"][1:-1])
    assert gyro_cfg1(2000, 10) == writes[0x01]
    assert MAX21105.gyro_odr_hz[4000] == writes[0x02]
    assert pwr_acc_cfg(MAX21105, 8) == writes[0x04]
    assert acc_cfg1(MAX21105, 48, 2000) == writes[0x05]


def test_register_codes_reproduce_har_in_air_max21100_configuration() -> None:
    # har-in-air: GYRO_CFG1 0x2D (150 Hz, 1000 dps), GYRO_CFG2 0x04 (500 Hz),
    # PWR_ACC_CFG 0x87 (4 g, XYZ on), ACC_CFG1 0x32 (ODR/3, 500 Hz), POWER_CFG 0x7F
    writes = dict(VECTORS["max21100"]["hmc5883l_master_config_har_in_air"][:10])
    assert gyro_cfg1(1000, 150) == writes[0x01]
    assert MAX21100.gyro_odr_hz[500] == writes[0x02]
    assert pwr_acc_cfg(MAX21100, 4) == writes[0x04]
    assert acc_cfg1(MAX21100, 3, 500) == writes[0x05]
    assert MAX21100.power_cfg_on == writes[0x00]


def test_odr_tables_follow_the_facts_and_differ_between_parts() -> None:
    assert list(MAX21100.gyro_odr_hz) == VECTORS["max21100"]["gyro_odr_code_hz"]
    assert list(MAX21100.accel_odr_hz) == VECTORS["max21100"]["accel_odr_code_hz"]
    assert MAX21100.accel_odr_hz[250] == 3  # the seed's 250 Hz accelerometer
    assert MAX21105.gyro_odr_hz[200] == 5 and MAX21105.accel_odr_hz[200] == 3


class _Spy(Bus):
    kind = BusKind.SPI

    def __init__(self) -> None:
        super().__init__("spy")
        self.sent: list[bytes] = []

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        self.sent.append(write)
        return bytes(read_len)


def test_spi_address_bytes_match_user_guide_default_mode_examples() -> None:
    spy = _Spy()
    view = RegisterView(spy.link(0), SPI_CONVENTION)
    view.read(0x24, 12)  # burst with auto-increment
    view.read_u8(0x3E)  # single access: bit 6 set, no increment
    view.write(0x22, 0x00)
    examples = {e["desc"]: e["byte"] for e in VECTORS["max21105_spi_examples"]}
    assert spy.sent[0][0] == examples["burst read from 0x24 with auto-increment"]
    assert spy.sent[1][0] == examples["burst read FIFO_DATA 0x3E without increment"]
    assert spy.sent[2][0] & 0x80 == 0 and spy.sent[2][0] & 0x3F == 0x22


def test_seed_configurations_are_the_settings_defaults() -> None:
    s0 = Max21100Settings()
    assert (s0.gyro_range_dps, s0.gyro_lpf_hz, s0.gyro_odr_hz) == (500, 14, 250)
    assert (s0.accel_range_g, s0.accel_lpf_divisor, s0.accel_odr_hz) == (4, 48, 250)
    s5 = Max21105Settings()
    assert (s5.gyro_range_dps, s5.gyro_lpf_hz, s5.gyro_odr_hz) == (1000, 10, 200)
    assert (s5.accel_range_g, s5.accel_lpf_divisor, s5.accel_odr_hz) == (8, 48, 200)


def test_unsupported_setting_error_lists_the_allowed_values() -> None:
    with pytest.raises(ValidationError, match=r"allowed: 250, 500, 1000, 2000 dps"):
        Max21100Settings(gyro_range_dps=300)
    with pytest.raises(ValidationError, match=r"accel_lpf.*allowed: 3, 9, 22, 48"):
        Max21100Settings(accel_lpf_divisor=10)


def test_odr_validation_uses_each_parts_own_table() -> None:
    Max21100Settings(gyro_odr_hz=62.5)
    with pytest.raises(ValidationError, match=r"MAX21105.*allowed: .*10, 25, 50, 100, 200"):
        Max21105Settings(gyro_odr_hz=62.5)
    with pytest.raises(ValidationError, match=r"MAX21100"):
        Max21100Settings(accel_odr_hz=200)


def test_unknown_setting_names_are_rejected() -> None:
    with pytest.raises(ValidationError):
        Max21100Settings(gyro_fs=500)  # type: ignore[call-arg]
