"""MPU-9250 decoding and register tables as pure functions, against the reference vectors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from imuhal_chips.mpu9250 import registers as r
from imuhal_chips.mpu9250.decode import (
    accel_m_s2,
    decode_counts,
    gyro_rad_s,
    saturated,
    temperature_degc,
)

VECTORS = json.loads((Path(__file__).parent.parent / "data/chips/mpu9250_vectors.json")
                     .read_text())


def test_example_burst_decodes_big_endian_accel_temp_gyro() -> None:
    ex = VECTORS["example_sample"]
    raw = decode_counts(bytes(ex["bytes_0x3B_0x48"]))
    assert raw.accel == tuple(ex["accel_raw"])
    assert raw.temperature == ex["temp_raw"]
    assert raw.gyro == tuple(ex["gyro_raw"])


def test_example_burst_at_fs0_in_si_units() -> None:
    ex = VECTORS["example_sample"]
    raw = decode_counts(bytes(ex["bytes_0x3B_0x48"]))
    want = ex["at_FS0"]
    assert accel_m_s2(raw.accel, 16384) == pytest.approx(
        [g * r.STANDARD_GRAVITY_M_S2 for g in want["accel_g"]], abs=1e-12)
    assert gyro_rad_s(raw.gyro, 131.0) == pytest.approx(
        [math.radians(d) for d in want["gyro_dps"]], abs=1e-12)
    assert temperature_degc(raw.temperature) == pytest.approx(want["temp_C"], abs=1e-12)


@pytest.mark.parametrize(("raw", "want"), VECTORS["temp"]["examples"])
def test_temperature_examples(raw: int, want: float) -> None:
    assert temperature_degc(raw) == pytest.approx(want, abs=1e-12)


def test_range_tables_match_the_reference_codes_and_sensitivities() -> None:
    for i, dps in enumerate((250, 500, 1000, 2000)):
        assert r.GYRO_RANGES[dps].config_value == VECTORS["gyro_config_values"][f"{dps}dps"]
        assert r.GYRO_RANGES[dps].lsb_per_unit == VECTORS["gyro_lsb_per_dps_by_FS_SEL"][i]
    for i, g in enumerate((2, 4, 8, 16)):
        assert r.ACCEL_RANGES[g].config_value == VECTORS["accel_config_values"][f"{g}g"]
        assert r.ACCEL_RANGES[g].lsb_per_unit == VECTORS["accel_lsb_per_g_by_FS_SEL"][i]


def test_sample_rate_divider_applies_only_with_dlpf_1_to_6() -> None:
    assert r.sample_rate_hz(r.GYRO_DLPF[41], 4) == 200.0
    assert r.sample_rate_hz(r.GYRO_DLPF[250], 4) == 8000.0
    assert r.sample_rate_hz(r.GYRO_DLPF[3600], 9) == 8000.0


def test_saturation_is_the_16_bit_limit() -> None:
    assert saturated((0, 32767, 0)) and saturated((-32768, 0, 0))
    assert not saturated((32766, -32767, 0))
