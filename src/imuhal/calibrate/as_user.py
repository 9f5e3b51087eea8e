"""What ``imuhal run`` does about the calibrations a profile lacks.

On real hardware (or an emulated board flown as its file says) it says once, per device and
channel, that a record is missing and what that may cost: the tilt an accelerometer offset
of the size the chip's driver declares (``Driver.specified_offset``, from the datasheet)
reads as, or that the magnetometer's offset and the board's iron turn the heading.

An emulated board is instead calibrated first, as its user would after following
docs/calibration.md (:func:`imuhal.emulation.calibrated_as_user`), and the records are
written into the profile's text (as ``imuhal calibrate`` writes them, nine significant
digits), so that the run, and a ``--record``ing of it, use exactly what a user's calibrated
copy of the profile would hold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from imuhal.calibrate.store import replace_device_calibration, rounded
from imuhal.calibration.model import DeviceCalibration
from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.atomic import atomic_write_text
from imuhal.core.samples import Quantity
from imuhal.emulation import calibrated_as_user
from imuhal.emulation.user_calibration import missing_calibrations
from imuhal.pipeline.learning import learned_by_default
from imuhal.plugins.manager import Registry
from imuhal.profile.loader import parse_profile
from imuhal.profile.model import BoardProfile

_WORDS = {Quantity.ACCEL.value: "accelerometer", Quantity.MAG.value: "magnetometer"}


def tilt_from_offset_deg(offset_m_s2: float) -> float:
    """The tilt (deg) about a level axis that an accelerometer offset of ``offset_m_s2`` on
    that axis reads as at rest: a horizontal offset is indistinguishable from tilting
    gravity onto the axis."""
    return math.degrees(math.atan2(offset_m_s2, STANDARD_GRAVITY_M_S2))


def missing_calibration_notes(profile: BoardProfile, registry: Registry,
                              command: str = "imuhal calibrate") -> list[str]:
    """One line per device and channel the profile has no accelerometer or magnetometer
    record for: what it may cost and the command that measures it."""
    notes = []
    for device, channels in missing_calibrations(profile, registry).items():
        driver = profile.devices[device].driver
        declared = registry.drivers.get(driver).specified_offset
        for channel in channels:
            offset = declared.get(channel)
            head = f"device {device!r} ({driver}) has no {_WORDS[channel.value]} calibration"
            fix = f"measure it with `{command} {channel.value} PROFILE` (docs/calibration.md)"
            if channel is Quantity.ACCEL and offset is not None:
                cost = (f"its offset (up to {offset / STANDARD_GRAVITY_M_S2 * 1e3:.0f} mg per "
                        f"axis for this chip) reads as a tilt of up to "
                        f"{tilt_from_offset_deg(offset):.1f} deg about each level axis")
            elif channel is Quantity.ACCEL:
                cost = "its offset (not specified by the driver) reads as a tilt"
            else:
                size = "" if offset is None else \
                    f" (up to {offset:.0f} uT per axis for this chip)"
                cost = (f"its offset{size} and the board's hard and soft iron turn the "
                        "heading of every 9-DOF estimate")
            notes.append(f"{head}: {cost}; {fix}")
    return notes


_LEARNS = {Quantity.ACCEL: "its accelerometer's offset (from the GNSS velocity)",
           Quantity.MAG: "its magnetometer's hard iron (from turns)"}


def default_learning_notes(profile: BoardProfile, registry: Registry) -> list[str]:
    """One line per device that learns in flight by default (its profile stores no record
    and does not say; imuhal.pipeline.learning): what it learns and how to turn it off."""
    notes = []
    for device, channels in learned_by_default(profile, registry).items():
        what = " and ".join(_LEARNS[ch] for ch in channels)
        off = " and ".join(f"`{ch.value}_in_flight: off`" for ch in channels)
        notes.append(f"device {device!r} ({profile.devices[device].driver}) learns {what} "
                     f"in flight by default, as its profile stores no record; {off} under "
                     f"devices.{device}.calibration turns it off (docs/calibration.md)")
    return notes


@dataclass(frozen=True)
class CalibratedRun:
    """A profile after the emulated user calibrated it."""

    profile: BoardProfile
    text: str
    """The profile's YAML with the measured records written in."""
    measured: dict[str, tuple[str, ...]]
    """device -> the channels measured (``accel``, ``mag``); empty: nothing was missing."""

    def describe(self, scenario_seed: int) -> str:
        """One line for the run's output: what was measured, how, and how to skip it."""
        what = ", ".join(
            f"the {_WORDS[ch]} of {device!r} "
            f"({'six positions' if ch == 'accel' else 'figure of 8, ellipsoid'})"
            for device, channels in self.measured.items() for ch in channels)
        return (f"calibrated first, as docs/calibration.md asks of a new board: {what}, "
                "measured by imuhal's procedures on the emulated board flying 'calibration' "
                f"(seed {scenario_seed}); add --skip-calibration to fly it as the profile "
                "stores it")


def calibrate_emulated(profile: BoardProfile, text: str, source: str, registry: Registry,
                       *, seed: int | None = None) -> CalibratedRun:
    """``profile`` (read from ``text``) with the accelerometer and magnetometer records it
    lacks measured on its emulated board with ``seed`` (default: the profile's) and written
    into its text, as ``imuhal calibrate`` writes them."""
    calibrated, missing = calibrated_as_user(profile, registry, seed=seed)
    if not missing:
        return CalibratedRun(profile, text, {})
    for device in missing:
        cal = calibrated.devices[device].calibration
        assert cal is not None  # calibrated_as_user measured it
        text, _ = replace_device_calibration(text, source, device, rounded(cal))
    return CalibratedRun(parse_profile(text, source, registry), text,
                         {d: tuple(ch.value for ch in chans) for d, chans in missing.items()})


def save_learned(text: str, source: str, output: str,
                 calibrations: dict[str, DeviceCalibration], registry: Registry) -> None:
    """Write a copy of the profile (``text``, read from ``source``) to ``output`` with each
    device's calibration replaced by ``calibrations`` (the records learned in flight, as
    ``imuhal calibrate`` writes records), atomically; the copy must load as a profile."""
    for device, cal in calibrations.items():
        text, _ = replace_device_calibration(text, source, device, rounded(cal))
    parse_profile(text, output, registry)
    atomic_write_text(output, text)
