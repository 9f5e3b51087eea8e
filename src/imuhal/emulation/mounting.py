"""How each emulated chip is mounted: its chip -> body rotation, worked out from the profile by
the emulation's own code.

The pipeline rotates samples chip -> body with
:func:`imuhal.profile.topology.chip_to_body_rotations`. The emulated board must not reuse it:
the board rotates the truth body -> chip with these matrices and the pipeline rotates the
samples back, so a mistake shared by both (a misread mount string, the mount and
``board_to_body`` composed in the wrong order) would cancel and no test could see it. Here the
same documented meaning (docs/units-and-frames.md) is implemented separately: a signed-axis
string names, for body x, y and z in turn, the sensor axis that points that way; a 3x3 matrix
M maps v_body = M v_sensor; the chip's rotation is board_to_body applied after the mount.
The profile loader has already checked that every mount is a proper rotation.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from imuhal.core.frames import FloatArray
from imuhal.profile.model import BoardProfile

Matrix = list[list[float]]

_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}


def _matrix(spec: str | Sequence[Sequence[float]]) -> Matrix:
    """v_body = M v_sensor for one mount specification."""
    if not isinstance(spec, str):
        return [[float(v) for v in row] for row in spec]
    rows: Matrix = []
    sign = 1.0
    for ch in spec.replace(" ", "").upper():
        if ch in "+-":
            sign = -1.0 if ch == "-" else 1.0
            continue
        row = [0.0, 0.0, 0.0]
        row[_AXIS_INDEX[ch]] = sign  # this body axis is that sensor axis, with that sign
        rows.append(row)
        sign = 1.0
    return rows


def _product(outer: Matrix, inner: Matrix) -> Matrix:
    """outer @ inner: first ``inner``, then ``outer``."""
    return [[sum(outer[i][k] * inner[k][j] for k in range(3)) for j in range(3)]
            for i in range(3)]


def chip_rotations(profile: BoardProfile) -> dict[str, FloatArray]:
    """Each enabled device's chip -> body rotation: its mount (chip -> board), then the
    board's ``board_to_body`` (board -> body)."""
    board = _matrix(profile.board_to_body)
    return {name: np.array(_product(board, _matrix(dev.mount)))
            for name, dev in profile.devices.items() if dev.enabled}
