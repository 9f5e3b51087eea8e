"""BMP280 compensation as pure functions: the datasheet worked example, bit-exact."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from imuhal_chips.bmp280.compensation import (
    DATASHEET_TRIM,
    Trim,
    compensate_pressure_int32,
    compensate_pressure_int64,
    compensate_temperature_int32,
    decode_adc,
    encode_adc,
)
from imuhal_chips.bmp280.emulator_encoding import (
    DATASHEET_TRIMMING,
    adc_p_for,
    adc_t_for,
    t_fine_of,
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


def test_emulator_encoding_inverts_to_the_worked_example_adc_values() -> None:
    """The emulator's closed-form inverse of the double formula lands on the example's ADC
    values; the driver's compensation of those values is the worked example."""
    adc_t = adc_t_for(25.08247793081682, DATASHEET_TRIMMING)
    assert round(adc_t) == VECTORS["adc_T"]
    t_fine = t_fine_of(VECTORS["adc_T"], DATASHEET_TRIMMING)
    assert round(adc_p_for(100653.2668, t_fine, DATASHEET_TRIMMING)) == VECTORS["adc_P"]


@pytest.mark.parametrize("temperature_degc", [-40.0, -10.0, 0.0, 25.0, 60.0, 85.0])
def test_driver_compensates_emulator_encoding_to_the_truth(temperature_degc: float) -> None:
    """Against the emulator's independent encoding: within one 20-bit step plus the 0.45 Pa
    by which the 64-bit integer and double formulas differ."""
    for pressure_pa in (30_000.0, 50_000.0, 70_000.0, 90_123.0, 101_325.0, 110_000.0):
        adc_t = round(adc_t_for(temperature_degc, DATASHEET_TRIMMING))
        adc_p = round(adc_p_for(pressure_pa, t_fine_of(adc_t, DATASHEET_TRIMMING),
                                DATASHEET_TRIMMING))
        t_centi, t_fine = compensate_temperature_int32(adc_t, DATASHEET_TRIM)
        assert abs(t_centi / 100 - temperature_degc) <= 0.01
        got = compensate_pressure_int64(adc_p, t_fine, DATASHEET_TRIM) / 256
        assert abs(got - pressure_pa) <= 0.5, (pressure_pa, temperature_degc)
