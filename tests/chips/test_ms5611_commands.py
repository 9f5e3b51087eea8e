"""MS5611 command bytes and conversion timing agree with the datasheet table (vectors file)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from imuhal_chips.ms5611.commands import (
    ADC_READ,
    OSR_TIMING,
    OSR_VALUES,
    RESET,
    RESET_RELOAD_MS,
    Measurement,
    convert_command,
    decode_command,
    prom_read_command,
)

VECTORS = json.loads(
    (Path(__file__).parent.parent / "data" / "chips" / "ms5611_vectors.json").read_text()
)


def test_reset_and_adc_read_bytes() -> None:
    assert VECTORS["commands"]["reset"] == RESET
    assert VECTORS["commands"]["adc_read"] == ADC_READ


def test_prom_read_bytes_for_words_0_to_7() -> None:
    assert [prom_read_command(n) for n in range(8)] == VECTORS["commands"]["prom_read"]


def test_prom_read_rejects_word_8() -> None:
    with pytest.raises(ValueError, match=r"0\.\.7"):
        prom_read_command(8)


@pytest.mark.parametrize("osr", OSR_VALUES)
def test_convert_bytes_per_osr(osr: int) -> None:
    assert convert_command(Measurement.D1, osr) == VECTORS["commands"]["convert_d1"][str(osr)]
    assert convert_command(Measurement.D2, osr) == VECTORS["commands"]["convert_d2"][str(osr)]


@pytest.mark.parametrize("osr", OSR_VALUES)
def test_conversion_times_per_osr(osr: int) -> None:
    expected = VECTORS["conversion_time_ms"][str(osr)]
    timing = OSR_TIMING[osr]
    assert (timing.min_ms, timing.typ_ms, timing.max_ms) == (
        expected["min"], expected["typ"], expected["max"]
    )
    assert timing.typ_ns < timing.max_ns


def test_reset_reload_time() -> None:
    assert VECTORS["reset_reload_ms"] == RESET_RELOAD_MS


@pytest.mark.parametrize("osr", OSR_VALUES)
def test_decode_inverts_convert(osr: int) -> None:
    for measurement in Measurement:
        decoded = decode_command(convert_command(measurement, osr))
        assert (decoded.action, decoded.measurement, decoded.osr) == ("convert", measurement, osr)


def test_decode_unlisted_byte_is_unknown() -> None:
    assert decode_command(0x4A).action == "unknown"  # convert D1 with the unused OSR index 5
