"""Frames at the edges of ``imuhal estimate``: input columns from any named convention into
imuhal's NED body frame, and the output columns' convention.

The input's gyro, accelerometer and magnetometer columns are read in the body axes (and, for
the accelerometer, the sign) of ``--input-frame`` and converted exactly to NED before any
sample is built, so the estimator sees what it would see live. Columns named with a frame
suffix, as imuhal writes them (``ax_m_s2_enu``), say their frame themselves. Vertical-filter
columns (``altitude_m``, ``accel_up_m_s2``, ``pressure_pa``) have no frame.
"""

from __future__ import annotations

import numpy as np

from imuhal.core.conventions import (
    CONVENTIONS,
    NED,
    Convention,
    VectorKind,
    get_convention,
    vector_to_ned,
)
from imuhal.estimation.framed import frame_suffix
from imuhal.offline.csv_input import ACCEL, GYRO, MAG, InputError, SampleTable

_VECTORS = ((GYRO, VectorKind.ANGULAR_RATE), (ACCEL, VectorKind.SPECIFIC_FORCE),
            (MAG, VectorKind.MAGNETIC_FIELD))


def table_to_ned(table: SampleTable, frame: str | Convention) -> SampleTable:
    """``table`` with its body-frame vector columns converted from ``frame`` to NED (a new
    table; the input is untouched). Empty cells of a sparse column stay empty."""
    c = get_convention(frame)
    if c is NED:
        return table
    columns = dict(table.columns)
    for names, kind in _VECTORS:
        if not table.has(*names):
            continue
        stacked = np.stack([table.columns[n] for n in names], axis=-1)
        converted = vector_to_ned(stacked, c, kind)
        for i, n in enumerate(names):
            columns[n] = converted[:, i]
    return SampleTable(table.path, columns, table.lines)


def _vector_names(frame: Convention) -> list[str]:
    sfx = frame_suffix(frame)
    return [n + sfx for names, _ in _VECTORS for n in names]


def resolve_input_frame(table: SampleTable,
                        requested: Convention | None) -> tuple[SampleTable, Convention]:
    """The table with frame-suffixed vector columns renamed to the plain names, and the frame
    its vectors are in: the suffix's, else ``requested``, else ned. A suffix that contradicts
    ``requested``, or columns in two frames at once, is an InputError naming them."""
    suffixed = {c.name: [n for n in _vector_names(c) if n in table.columns]
                for c in CONVENTIONS.values() if c is not NED}
    suffixed = {k: v for k, v in suffixed.items() if v}
    if not suffixed:
        return table, requested or NED
    plain = [n for n in _vector_names(NED) if n in table.columns]
    if len(suffixed) > 1 or plain:
        found = sorted({n for names in suffixed.values() for n in names} | set(plain))
        raise InputError(f"{table.path}: vector columns in more than one frame "
                         f"({', '.join(found)}); keep one frame per file")
    (name, names), = suffixed.items()
    frame = CONVENTIONS[name]
    if requested is not None and requested is not frame:
        raise InputError(f"{table.path}: column {names[0]} is in frame '{name}' but "
                         f"--input-frame {requested.name} was given; drop --input-frame or "
                         "rename the columns")
    sfx = frame_suffix(frame)
    columns = {(k[: -len(sfx)] if k in names else k): v for k, v in table.columns.items()}
    return SampleTable(table.path, columns, table.lines), frame
