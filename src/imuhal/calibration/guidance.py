"""Words and order for the accelerometer's six positions, through the board's mount: which
way a person turns the board for each sensor axis, and the order they handle it in.

Pure functions of a chip-to-body rotation (no I/O), shared by ``imuhal calibrate accel``
and the emulated board's calibration (imuhal.emulation.user_calibration).
"""

from __future__ import annotations

import numpy as np

from imuhal.calibration.accel import SIX_POSITIONS, Position, position_name
from imuhal.core.frames import FloatArray

_BODY_WORDS = {
    (2, 1): "level, top up",
    (2, -1): "upside down",
    (0, 1): "nose down (front edge down)",
    (0, -1): "nose up (rear edge down)",
    (1, 1): "right side down",
    (1, -1): "left side down",
}
_BODY_ORDER = [(2, 1), (2, -1), (0, 1), (0, -1), (1, 1), (1, -1)]


def _body_down(pos: Position, chip_to_body: FloatArray) -> Position | None:
    d = np.asarray(chip_to_body, dtype=float) @ (pos[1] * np.eye(3)[pos[0]])
    axis = int(np.argmax(np.abs(d)))
    if abs(d[axis]) < 0.99:
        return None
    return (axis, 1 if d[axis] > 0 else -1)


def describe_position(pos: Position, chip_to_body: FloatArray) -> str:
    """Words for the user: which way the board goes, with the sensor axis for reference."""
    body = _body_down(pos, chip_to_body)
    words = _BODY_WORDS[body] if body is not None else "turn the board"
    return f"{words} (sensor {position_name(pos)})"


def guided_order(chip_to_body: FloatArray) -> tuple[str, ...]:
    """The six sensor positions in the order a person handles a board: level, upside down,
    nose down, nose up, right side down, left side down."""
    def rank(p: Position) -> int:
        body = _body_down(p, chip_to_body)
        return _BODY_ORDER.index(body) if body is not None else len(_BODY_ORDER)
    return tuple(position_name(p) for p in sorted(SIX_POSITIONS, key=rank))
