"""BMP280 compensation as pure functions: the datasheet worked example, bit-exact."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from imuhal_chips.bmp280.compensation import (
    DATASHEET_TRIM,
    Trim,
    adc_for_pressure,
    adc_for_temperature,
    compensate_pressure_int32,
    compensate_pressure_int64,
    compensate_temperature_int32,
    decode_adc,
    encode_adc,
)

VECTORS = json.loads((Path(__file__).parent.parent / "data/chips/bmp280_vectors.json")
                     .read_text())["datasheet_example"]


def test_trim_bytes_parse_to_the_worked_example_words() -> None:
    trim = Trim.from_bytes(bytes(VECTORS["calib_bytes_0x88_0x9F_little_endian"]))
    assert trim == Trim(**VECTORS["dig"])


def test_trim_t1_and_p1_are_unsigned_the_rest_signed() -> None:
    data = bytes([0xFF, 0xFF] * 12)
    trim = Trim.from_bytes(data)
    assert (trim.T1, trim.P1) == (65535, 65535)
    assert trim.T2 == trim.T3 == trim.P2 == trim.P9 == -1


def test_data_bytes_decode_to_the_worked_example_adc_values() -> None:
    adc_p, adc_t = decode_adc(bytes(VECTORS["data_bytes_0xF7_0xFC"]))
    assert (adc_p, adc_t) == (VECTORS["adc_P"], VECTORS["adc_T"])
    assert encode_adc(adc_p) + encode_adc(adc_t) == bytes(VECTORS["data_bytes_0xF7_0xFC"])


def test_temperature_int32_gives_t_fine_128422_and_2508_centidegrees() -> None:
    t, t_fine = compensate_temperature_int32(VECTORS["adc_T"], DATASHEET_TRIM)
    assert (t, t_fine) == (2508, 128422)


def test_pressure_int64_gives_25767233_q24_8() -> None:
    # The datasheet prints 25767236, which its own formula does not produce (facts note 8).
    p = compensate_pressure_int64(VECTORS["adc_P"], 128422, DATASHEET_TRIM)
    assert p == 25767233
    assert p / 256 == pytest.approx(100653.27, abs=0.05)


def test_pressure_int32_gives_100656_pa() -> None:
    assert compensate_pressure_int32(VECTORS["adc_P"], 128422, DATASHEET_TRIM) == 100656


def test_shifts_floor_negative_values_like_the_datasheet() -> None:
    # Far below the trim's reference temperature var1 is negative; a truncating division
    # (Bosch driver v3.3.4) would round it toward zero and give a larger t_fine.
    adc_t = 300000
    _, t_fine = compensate_temperature_int32(adc_t, DATASHEET_TRIM)
    var1 = (((adc_t >> 3) - (27504 << 1)) * 26435) >> 11
    assert var1 < 0
    assert t_fine == var1 + ((((adc_t >> 4) - 27504) ** 2 >> 12) * -1000 >> 14)


def test_int32_path_wraps_like_c_at_extreme_inputs() -> None:
    # adc_P = 0 makes (1048576 - adc_P - var2>>12) * 3125 exceed 2^31: the C code takes its
    # unsigned branch; the result must stay a uint32, never a Python big integer.
    p = compensate_pressure_int32(0, 128422, DATASHEET_TRIM)
    assert 0 <= p < 2**32


@pytest.mark.parametrize("bits", [16, 18, 20])
def test_inverse_search_finds_the_worked_example_adc_values(bits: int) -> None:
    adc_t = adc_for_temperature(25.08247793081682, DATASHEET_TRIM, bits)
    assert adc_t % (1 << (20 - bits)) == 0
    assert abs(adc_t - VECTORS["adc_T"]) <= (1 << (20 - bits)) // 2
    if bits == 20:
        assert adc_t == VECTORS["adc_T"]
        assert adc_for_pressure(100653.2539, 128422, DATASHEET_TRIM) == VECTORS["adc_P"]
