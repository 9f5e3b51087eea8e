"""AK8963 decoding as pure functions: ASA adjustment, little-endian data, status bits, axes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from imuhal.core.frames import parse_mount
from imuhal_chips.ak8963.decode import asa_factor, decode_burst, decode_counts, to_mpu9250_axes

VECTORS = json.loads((Path(__file__).parent.parent / "data/chips/ak8963_vectors.json")
                     .read_text())


@pytest.mark.parametrize("example", VECTORS["asa_examples"], ids=lambda e: f"asa={e['asa']}")
def test_asa_factor_matches_the_reference_examples(example: dict[str, float]) -> None:
    assert asa_factor(int(example["asa"])) == example["factor"]


def test_hadj_example_gives_178_125_ut_in_16_bit() -> None:
    ex = VECTORS["hadj_example"]
    h = ex["H"]
    burst = bytes([0x01]) + h.to_bytes(2, "little", signed=True) + bytes(4) + bytes([0x10])
    m = decode_burst(burst, (ex["asa"], 128, 128))
    assert m.counts[0] * asa_factor(ex["asa"]) == ex["Hadj"]
    assert m.field_ut[0] == pytest.approx(ex["uT_16bit"], abs=1e-9)


def test_data_bytes_are_little_endian_signed() -> None:
    ex = VECTORS["example_read"]
    assert decode_counts(bytes(ex["bytes_0x03_0x09"][:6])) == tuple(ex["xyz_raw"])


def test_burst_decodes_status_and_scales_by_bitm() -> None:
    ex = VECTORS["example_read"]
    burst = bytes([0x01, *ex["bytes_0x03_0x09"]])
    m = decode_burst(burst, (128, 128, 128))
    assert m.data_ready and not m.data_overrun and not m.overflow and m.bits == 16
    assert m.field_ut == pytest.approx((1500.0, -1500.0, 150.0), abs=1e-9)
    m14 = decode_burst(burst[:-1] + bytes([0x00]), (128, 128, 128))
    assert m14.bits == 14 and m14.field_ut[2] == pytest.approx(600.0, abs=1e-9)


def test_hofl_and_dor_and_range_limit_are_reported() -> None:
    limit = (32760).to_bytes(2, "little", signed=True)
    burst = bytes([0x03]) + limit + bytes(4) + bytes([0x18])
    m = decode_burst(burst, (128, 128, 128))
    assert m.data_ready and m.data_overrun and m.overflow and m.saturated


def test_axes_relative_to_mpu9250_follow_the_reference_example() -> None:
    ex = VECTORS["orientation_vs_mpu9250_accel_gyro"]["example"]
    assert to_mpu9250_axes(tuple(ex["mag_xyz"])) == tuple(ex["in_accel_frame"])


def test_gy91_mount_string_takes_the_ak8963_frame_to_the_same_body_axes_as_the_mpu() -> None:
    # GY-91 with the MPU-9250 mounted "+X-Y-Z" (chip X forward, Y left, Z up -> NED body):
    # the AK8963 needs "+Y-X+Z" so both land on the same body axes.
    mag = (10.0, 20.0, 30.0)
    via_mpu = parse_mount("+X-Y-Z") @ np.array(to_mpu9250_axes(mag))
    direct = parse_mount("+Y-X+Z") @ np.array(mag)
    assert direct.tolist() == via_mpu.tolist()
