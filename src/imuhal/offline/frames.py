"""Frames at the edges of ``imuhal estimate``: input columns from any named convention into
imuhal's NED body frame, and the output columns' convention.

The input's gyro, accelerometer and magnetometer columns are read in the body axes (and, for
the accelerometer, the sign) of ``--input-frame`` and converted exactly to NED before any
sample is built, so the estimator sees what it would see live. Vertical-filter columns
(``altitude_m``, ``accel_up_m_s2``, ``pressure_pa``) have no frame.
"""

from __future__ import annotations

import numpy as np

from imuhal.core.conventions import (
    NED,
    Convention,
    UnknownConvention,
    VectorKind,
    get_convention,
    vector_to_ned,
)
from imuhal.offline.csv_input import ACCEL, GYRO, MAG, SampleTable

_VECTORS = ((GYRO, VectorKind.ANGULAR_RATE), (ACCEL, VectorKind.SPECIFIC_FORCE),
            (MAG, VectorKind.MAGNETIC_FIELD))


def frame_argument(text: str) -> Convention:
    """An argparse ``type``: the named convention, or a one-line usage error listing them."""
    import argparse

    try:
        return get_convention(text)
    except UnknownConvention as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


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
