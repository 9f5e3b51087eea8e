"""CSV numbers a block at a time (imuhal.offline.fast_csv) are those of ``float()`` and
``repr()`` per cell, and ``imuhal estimate`` writes the same bytes with them as without.

The block reader must give every cell's ``float()`` bit for bit, or hand the block back to
the strict reader; the block writer must give every value's ``repr`` (``nan`` when not
finite). The reference is the per-cell path itself (``IMUHAL_FAST_CSV=0``).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from tests.filters.dataset_a import load_head

from imuhal.cli.main import main
from imuhal.offline.csv_input import ACCEL, GYRO, MAG, PRESSURE, TIME, iter_sample_chunks
from imuhal.offline.fast_csv import ENV, format_block, parse_block

pytest.importorskip("orjson")

HEADER = [TIME, *GYRO, *ACCEL, *MAG]


def _values(seed: int, n: int) -> np.ndarray:
    """Doubles of every magnitude a log may hold (and the awkward ones around 1e-4)."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(n) * 10.0 ** rng.integers(-9, 18, n)
    x[::17] = rng.integers(-1000, 1000, len(x[::17]))  # integral values
    x[1::23] = 1e-4 * (1 + rng.standard_normal(len(x[1::23])) * 1e-3)
    x[2::29] = rng.integers(1, 1 << 52, len(x[2::29])).astype(np.float64) * 5e-324  # subnormal
    x[3::31] = -0.0
    return x


def _as_text(values: np.ndarray, width: int, fmt: str) -> bytes:
    cells = [format(v, fmt) if fmt else repr(v) for v in values.tolist()]
    rows = [",".join(cells[i:i + width]) for i in range(0, len(cells), width)]
    return ("\n".join(rows) + "\n").encode()


@pytest.mark.parametrize("fmt", ["", ".9g", ".17e", ".3f"])
def test_block_reader_gives_each_cells_float_bit_for_bit(fmt: str) -> None:
    width = 5
    text = _as_text(np.abs(_values(1, 5000 * width)), width, fmt)  # no "-0": see below
    expected = np.array([float(c) for line in text.decode().split()
                         for c in line.split(",")]).reshape(-1, width)
    got = parse_block(text, text.count(b"\n"), width, [False] * width)
    assert got is not None
    assert np.array_equal(got.view(np.int64), expected.view(np.int64))


def test_block_reader_reads_empty_cells_of_sparse_columns_as_nan() -> None:
    text = b"0.1,1,,\n0.2,2,3.5,\n0.3,3,,7\n"
    got = parse_block(text, 3, 4, [False, False, True, True])
    assert got is not None
    assert np.array_equal(got, [[0.1, 1, np.nan, np.nan], [0.2, 2, 3.5, np.nan],
                                [0.3, 3, np.nan, 7]], equal_nan=True)


def test_block_reader_takes_windows_line_ends() -> None:
    got = parse_block(b"0.1,2\r\n0.2,3\r\n", 2, 2, [False, False])
    assert got is not None and got.tolist() == [[0.1, 2.0], [0.2, 3.0]]


@pytest.mark.parametrize("text", [
    b"0.1,-0\n",          # JSON reads -0 as the integer 0: the sign would be lost
    b"0.1,+1\n",          # float() takes these, JSON does not
    b"0.1,.5\n",
    b"0.1,1.\n",
    b"0.1, 1\n",
    b'0.1,"1"\n',
    b"0.1,nan\n",
    b"0.1,inf\n",
    b"0.1,1e999\n",       # not finite
    b"0.1,1,2\n",         # a row of another width
    b"0.1,1\n\n",         # a blank line
    b"0.1,\n",            # an empty cell in a column that must have one
    b"0.1,true\n",
])
def test_block_reader_hands_other_text_to_the_strict_reader(text: bytes) -> None:
    assert parse_block(text, text.count(b"\n"), 2, [False, False]) is None


def test_block_reader_is_off_with_the_environment_switch(monkeypatch: pytest.MonkeyPatch
                                                         ) -> None:
    monkeypatch.setenv(ENV, "0")
    assert parse_block(b"0.1,2\n", 1, 2, [False, False]) is None


def test_negative_zero_keeps_its_sign_through_the_csv_reader(tmp_path: Path) -> None:
    src = tmp_path / "imu.csv"
    src.write_text(",".join(HEADER[:7]) + "\n" + "0.0,-0,0,1,0,0,-9.8\n0.004,0,0,1,0,0,-9.8\n")
    (table,) = iter_sample_chunks(src)
    assert np.signbit(table.columns[GYRO[0]]).tolist() == [True, False]


def test_block_writer_writes_each_values_repr() -> None:
    floats = _values(2, 20_000)
    floats[5::97] = np.nan
    floats[6::101] = np.inf
    ints = np.random.default_rng(3).integers(-5, 1 << 40, len(floats))
    flags = ints % 2 == 0
    columns = [floats, ints, flags, floats[::-1].copy()]
    expected = "".join(
        ",".join(repr(v) if not isinstance(v, float) or np.isfinite(v) else "nan"
                 for v in (a, int(b), int(c), d)) + "\r\n"
        for a, b, c, d in zip(*(col.tolist() for col in columns), strict=True))
    assert format_block(columns) == expected.encode()
    assert format_block([floats]) == "".join(
        (repr(v) if np.isfinite(v) else "nan") + "\r\n" for v in floats.tolist()).encode()


def _dataset_log(path: Path, rows: int = 1500) -> None:
    """Data set A as a wide log written with repr (what a user's script would write), the
    magnetometer every third row and a pressure column, as ``imuhal estimate`` takes it."""
    t, gyro, accel, mag, _ = load_head()
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow([*HEADER, PRESSURE])
        for i in range(min(rows, len(t))):
            m = mag[i].tolist() if i % 3 == 0 else ["", "", ""]
            w.writerow([repr(float(t[i])), *gyro[i].tolist(), *accel[i].tolist(), *m,
                        repr(101325.0 - 0.01 * i)])


@pytest.mark.parametrize("name", ["madgwick", "mahony", "imufilter", "vqf", "decoupled",
                                  "freescale-9dof", "freescale-6dof", "vario-kf3",
                                  "baro-vario"])
def test_estimate_writes_the_same_bytes_with_and_without_block_text(
        name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    src, fast, slow = tmp_path / "a.csv", tmp_path / "fast.csv", tmp_path / "slow.csv"
    _dataset_log(src)
    assert main(["estimate", name, str(src), "-o", str(fast)]) == 0
    monkeypatch.setenv(ENV, "0")
    assert main(["estimate", name, str(src), "-o", str(slow)]) == 0
    assert fast.stat().st_size > 1000
    assert fast.read_bytes() == slow.read_bytes()
