"""HMC5883L tables and pure decoding against the datasheet/facts vectors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pydantic import ValidationError

from imuhal.core.samples import SampleFlag
from imuhal_chips.hmc5883l import decode
from imuhal_chips.hmc5883l.driver import Hmc5883lSettings
from imuhal_chips.hmc5883l.registers import (
    IDENTITY,
    ODR_HZ,
    POWER_ON_DEFAULTS,
    RANGE_GAUSS,
    Reg,
    config_a,
    config_b,
)

VECTORS = json.loads((Path(__file__).parent.parent / "data/chips/hmc5883l_vectors.json")
                     .read_text())


def test_example_read_is_x_z_y_big_endian() -> None:
    ex = VECTORS["example_read"]
    counts = decode.data_counts_xyz(bytes(ex["bytes_0x03_0x08"]))
    assert list(counts) == ex["raw_xyz"]
    gain = VECTORS["gain_lsb_per_gauss_by_GN"][ex["gain_GN"]]
    ut = decode.counts_to_ut(counts, gain)
    assert [v / 100 for v in ut] == pytest.approx(ex["gauss_xyz"])


def test_encoding_round_trips_through_register_order() -> None:
    raw = decode.data_bytes_from_counts((300, 100, -200))
    assert raw == bytes(VECTORS["example_read"]["bytes_0x03_0x08"])


def test_overflow_sentinel_flags_overflow_and_other_out_of_range_values_are_flagged() -> None:
    assert VECTORS["overflow_value"] == -4096
    assert decode.counts_flags((-4096, 0, 12)) == SampleFlag.OVERFLOW
    assert decode.counts_flags((2047, -2048, 0)) == SampleFlag.OK
    assert decode.counts_flags((0, 3000, 0)) == SampleFlag.OUT_OF_RANGE


def test_encode_axis_overflows_outside_minus_2048_to_2047() -> None:
    gain = 1090.0
    assert decode.encode_axis(2047 / gain, gain) == 2047
    assert decode.encode_axis(2048 / gain, gain) == -4096
    assert decode.encode_axis(-2048 / gain, gain) == -2048
    assert decode.encode_axis(-2049 / gain, gain) == -4096


def test_gain_and_rate_tables_follow_the_datasheet() -> None:
    for code, (rng, gain) in enumerate(zip(VECTORS["recommended_range_gauss_by_GN"],
                                           VECTORS["gain_lsb_per_gauss_by_GN"], strict=True)):
        assert RANGE_GAUSS[rng] == (code, gain)
    for code, hz in enumerate(VECTORS["odr_hz_by_DO"][:7]):
        assert ODR_HZ[hz] == code


def test_datasheet_init_example_is_8_average_15_hz_gain_5() -> None:
    writes = dict(VECTORS["datasheet_init_sequence"])
    assert config_a(8, 15) == writes[Reg.CONFIG_A]
    assert config_b(4.7) == writes[Reg.CONFIG_B]


def test_identity_and_defaults_match_facts() -> None:
    assert list(IDENTITY) == VECTORS["id_regs_0x0A_0x0C"]
    d = VECTORS["defaults"]
    assert {0: d["CRA"], 1: d["CRB"], 2: d["MODE"]} == POWER_ON_DEFAULTS


def test_seed_settings_are_the_defaults_and_config_bytes() -> None:
    s = Hmc5883lSettings()
    assert (s.range_gauss, s.odr_hz, s.averaging) == (1.3, 75, 8)
    assert config_a(8, 75) == 0x78 and config_b(1.3) == 0x20  # har-in-air CRA 0x78


def test_unsupported_settings_list_allowed_values() -> None:
    with pytest.raises(ValidationError, match=r"allowed: 0.88, 1.3, 1.9, 2.5, 4, 4.7, 5.6, 8.1"):
        Hmc5883lSettings(range_gauss=2.0)
    with pytest.raises(ValidationError, match=r"odr_hz = 160 Hz.*allowed: 0.75, .* 75 Hz"):
        Hmc5883lSettings(odr_hz=160)
    with pytest.raises(ValidationError, match=r"allowed: 1, 2, 4, 8"):
        Hmc5883lSettings(averaging=3)
