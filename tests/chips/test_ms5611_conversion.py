"""MS5611 PROM CRC4 (AN520) and integer compensation (datasheet Fig.2/3); the driver's
compensation against the emulator's independent encoding."""

from __future__ import annotations

import json
import random
from dataclasses import asdict
from pathlib import Path

import pytest

from imuhal_chips.ms5611.conversion import (
    Coefficients,
    compensate,
    crc4,
    prom_is_valid,
    with_crc4,
)
from imuhal_chips.ms5611.emulator_encoding import (
    PromCoefficients,
    counts_for,
    d1_for,
    d2_for,
    prom_crc4,
)

VECTORS = json.loads(
    (Path(__file__).parent.parent / "data" / "chips" / "ms5611_vectors.json").read_text()
)
COMPENSATION = VECTORS["compensation"]
CRC = VECTORS["crc4_examples"]
DATASHEET = Coefficients(40127, 36924, 23317, 23282, 33464, 28312)


@pytest.mark.parametrize(
    "case", ["datasheet_example", "second_order_lt_20C", "second_order_lt_minus15C"]
)
def test_compensation_reproduces_every_intermediate(case: str) -> None:
    """Floor (arithmetic shift) semantics: C truncation would give e.g. TEMP 206, not 205."""
    vector = COMPENSATION[case]
    coeffs = Coefficients.from_prom(vector["prom_words"])
    result = compensate(coeffs, vector["d1"], vector["d2"])
    assert asdict(result) == vector["expected_floor_shift_semantics"]


def test_datasheet_example_in_physical_units() -> None:
    vector = COMPENSATION["datasheet_example"]
    result = compensate(DATASHEET, vector["d1"], vector["d2"])
    assert result.pressure_pa == 100009.0
    assert result.temperature_degc == pytest.approx(20.07, abs=1e-12)
    assert result.temperature_in_range and result.pressure_in_range


def test_coefficients_come_from_words_1_to_6() -> None:
    assert Coefficients.from_prom(COMPENSATION["datasheet_example"]["prom_words"]) == DATASHEET


def test_crc4_of_an520_table_is_0xb() -> None:
    assert crc4(CRC[0]["prom_words"]) == CRC[0]["crc4_computed"] == 0xB
    assert not prom_is_valid(CRC[0]["prom_words"])  # stored nibble 0 differs


def test_an520_table_with_word7_0x450b_is_valid() -> None:
    assert CRC[1]["prom_words"][7] == 0x450B
    assert crc4(CRC[1]["prom_words"]) == 0xB
    assert prom_is_valid(CRC[1]["prom_words"])


def test_all_zero_prom_rejected_although_crc_matches() -> None:
    words = CRC[2]["prom_words"]
    assert crc4(words) == (words[7] & 0xF)
    assert not prom_is_valid(words)


def test_all_ones_prom_rejected() -> None:
    assert not prom_is_valid(CRC[3]["prom_words"])


def test_synthetic_prom_with_datasheet_coefficients_is_valid() -> None:
    assert crc4(CRC[4]["prom_words"]) == CRC[4]["crc4_computed"]
    assert prom_is_valid(CRC[4]["prom_words"])


@pytest.mark.parametrize("word", range(8))
def test_any_single_bit_flip_is_detected(word: int) -> None:
    valid = CRC[4]["prom_words"]
    for bit in range(16):
        if word == 7 and bit < 8:
            continue  # word 7's low byte is excluded from the CRC (it holds the CRC)
        corrupted = list(valid)
        corrupted[word] ^= 1 << bit
        assert not prom_is_valid(corrupted), (word, bit)


def test_with_crc4_makes_a_prom_valid() -> None:
    assert with_crc4(CRC[0]["prom_words"]) == CRC[1]["prom_words"]


ELEMENT = PromCoefficients(40127, 36924, 23317, 23282, 33464, 28312)
"""The same part as the emulator's sensor element sees it."""


def encode_raw(_: Coefficients, pressure_pa: float, temperature_degc: float
               ) -> tuple[int, int]:
    """The emulator's counts for the truth (written from the datasheet, not the driver)."""
    return counts_for(ELEMENT, pressure_pa, temperature_degc)


def test_driver_and_emulator_crc4_agree_on_random_proms() -> None:
    rng = random.Random(5611)
    for _ in range(500):
        words = [rng.randrange(1 << 16) for _ in range(8)]
        assert crc4(words) == prom_crc4(words), words


# Chip resolution: P is an integer Pa, TEMP an integer 0.01 degC; the emulator picks the
# counts whose output is the nearest representable value, so the error is at most half a
# step of each.
P_TOL_PA = 0.5
T_TOL_DEGC = 0.005 + 1e-9


@pytest.mark.parametrize("temperature_degc", [-20.0 + 5.0 * i + 0.123 for i in range(17)])
def test_driver_compensates_emulator_counts_to_the_truth(temperature_degc: float) -> None:
    for i in range(17):
        pressure_pa = 30000.0 + 5000.0 * i + 0.37
        d1, d2 = encode_raw(DATASHEET, pressure_pa, temperature_degc)
        result = compensate(DATASHEET, d1, d2)
        assert abs(result.P - pressure_pa) <= P_TOL_PA, (pressure_pa, temperature_degc)
        assert abs(result.TEMP / 100.0 - temperature_degc) <= T_TOL_DEGC


def test_emulator_counts_for_datasheet_outputs_compensate_back() -> None:
    """The datasheet's (D1, D2) give (100009 Pa, 20.07 degC); encoding those values must land
    on counts that compensate to exactly the same outputs."""
    d1, d2 = encode_raw(DATASHEET, 100009.0, 20.07)
    result = compensate(DATASHEET, d1, d2)
    assert (result.P, result.TEMP) == (100009, 2007)


def test_emulator_counts_clamp_to_24_bit_and_never_zero() -> None:
    assert encode_raw(DATASHEET, 1e7, 1000.0) == (0xFFFFFF, 0xFFFFFF)
    assert encode_raw(DATASHEET, -1e7, -1000.0) == (1, 1)


def test_emulator_d1_resolves_a_fraction_of_a_pascal_like_the_chips_adc() -> None:
    """About 50 D1 counts per pascal: a 0.1 Pa change moves the word by a few counts, so the
    chip's own noise shows in D1 (and a frozen converter's repeated word stands out)."""
    d1, d2 = encode_raw(DATASHEET, 95000.2, 15.0)
    d1_up, d2_up = encode_raw(DATASHEET, 95000.3, 15.0)
    assert d2_up == d2
    assert 2 <= d1_up - d1 <= 10


@pytest.mark.parametrize("temperature_degc", [-40.0, -16.3, 3.7, 19.995, 20.0, 41.2, 85.0,
                                              float("nan"), float("inf"), float("-inf")])
def test_each_count_alone_is_the_count_of_the_pair(temperature_degc: float) -> None:
    # a conversion works out only the count it converts (d1_for, d2_for): the very counts
    # counts_for gives, at every temperature branch, pressures out of range and values
    # that are not finite
    for pressure_pa in (1000.0, 54321.6, 101325.49, 119999.5, 5e7, float("nan"),
                        float("inf"), float("-inf")):
        d1, d2 = counts_for(ELEMENT, pressure_pa, temperature_degc)
        assert d2_for(ELEMENT, temperature_degc) == d2
        assert d1_for(ELEMENT, pressure_pa, temperature_degc) == d1, pressure_pa
