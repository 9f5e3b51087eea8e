"""Writing a device's calibration back into its profile, atomically, keeping the rest of the
file (comments, order, formatting) as it was.

Only the ``calibration:`` block of one device is rewritten: the located YAML loader gives the
line and column of every key, so the block's lines are replaced (or a new block appended to
the device) and every other line is copied unchanged. The result is validated as a profile
before anything is written. Writing is atomic: the new text goes to a temporary file in the
same directory, which is flushed and fsync'ed, then renamed over the profile (and the
directory fsync'ed), so a crash leaves either the old or the new profile, never a mix. The
previous file is kept as ``PROFILE.bak``; the replaced records are also kept inside the
profile under ``calibration.previous``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

import yaml

from imuhal.calibration.errors import CalibrationWriteError
from imuhal.calibration.model import DeviceCalibration
from imuhal.core.atomic import atomic_write_text, keep_backup
from imuhal.core.errors import OutputError, ProfileError
from imuhal.plugins.manager import Registry
from imuhal.profile.loader import parse_profile, read_profile_text
from imuhal.profile.yaml_source import load_located

INDENT = 2


# --------------------------------------------------------------------------- emitting YAML
def _float(x: float) -> str:
    if not math.isfinite(x):
        return ".nan" if math.isnan(x) else (".inf" if x > 0 else "-.inf")
    text = format(x, ".9g")
    mantissa, _, exp = text.partition("e")
    if "." not in mantissa:  # PyYAML (YAML 1.1) reads 1e-05 as a string: write 1.0e-05
        mantissa += ".0"
    return f"{mantissa}e{exp}" if exp else mantissa


def _scalar(v: Any, key: str = "") -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return f"0x{v:02X}" if key == "address" else str(v)
    if isinstance(v, float):
        return _float(v)
    if isinstance(v, datetime):
        return _quoted(v.isoformat())
    if v is None:
        return "null"
    return _quoted(str(v))


def _quoted(s: str) -> str:
    """Plain when YAML reads it back as the same string, double-quoted otherwise."""
    plain = yaml.safe_dump(s, width=10_000).strip().removesuffix("...").strip()
    if "\n" not in plain and not plain.startswith(("'", '"')) and yaml.safe_load(plain) == s:
        return plain
    return yaml.safe_dump(s, default_style='"', width=10_000).strip().removesuffix("...").strip()


def _flow(v: Sequence[Any]) -> str:
    return "[" + ", ".join(_flow(x) if isinstance(x, (list, tuple)) else _scalar(x)
                           for x in v) + "]"


def emit_block(key: str, value: Mapping[str, Any], indent: int) -> list[str]:
    """``key:`` and ``value`` as block YAML lines at ``indent`` spaces (vectors and matrices
    in flow style, one per line)."""
    pad = " " * indent
    lines = [f"{pad}{key}:"]
    for k, v in value.items():
        if isinstance(v, Mapping):
            if v:
                lines += emit_block(str(k), v, indent + INDENT)
            else:
                lines.append(f"{pad}{' ' * INDENT}{k}: {{}}")
        elif isinstance(v, (list, tuple)):
            lines.append(f"{pad}{' ' * INDENT}{k}: {_flow(v)}")
        else:
            lines.append(f"{pad}{' ' * INDENT}{k}: {_scalar(v, str(k))}")
    return lines


_META = ("procedure", "date", "binding", "quality")


def calibration_data(cal: DeviceCalibration) -> dict[str, Any]:
    """What is written: set fields only; in each record the values first, then how, when
    and on what they were measured."""
    data = cal.model_dump(mode="python", exclude_none=True)

    def ordered(rec: dict[str, Any]) -> dict[str, Any]:
        return {**{k: v for k, v in rec.items() if k not in _META},
                **{k: rec[k] for k in _META if k in rec}}

    for channel in ("accel", "gyro", "mag"):
        if channel in data:
            data[channel] = ordered(data[channel])
        if channel in data.get("previous", {}):
            data["previous"][channel] = ordered(data["previous"][channel])
    return data


def rounded(cal: DeviceCalibration) -> DeviceCalibration:
    """``cal`` with every float as written (9 significant digits), so that what is written
    reads back equal."""
    def walk(v: Any) -> Any:
        if isinstance(v, float):
            return float(_float(v)) if math.isfinite(v) else v
        if isinstance(v, Mapping):
            return {k: walk(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [walk(x) for x in v]
        return v
    return DeviceCalibration.model_validate(walk(calibration_data(cal)))


# --------------------------------------------------------------------------- rewriting
def _indent(line: str) -> int:
    return len(line) - len(line.lstrip(" "))


def _is_content(line: str) -> bool:
    s = line.strip()
    return bool(s) and not s.startswith("#")


def _block_end(lines: list[str], start: int, key_col: int) -> int:
    """Index after the last content line of the block whose key is on ``lines[start]`` at
    column ``key_col`` (0-based): lines indented deeper than the key belong to it."""
    last = start
    for i in range(start + 1, len(lines)):
        if not lines[i].strip():
            continue
        if _indent(lines[i]) <= key_col:
            if _is_content(lines[i]):
                break
            continue  # a comment at the key's level may introduce the next key: look on
        last = i
    return last + 1


def replace_device_calibration(text: str, source: str, device: str,
                               calibration: DeviceCalibration) -> tuple[str, list[str]]:
    """``text`` with ``devices.DEVICE.calibration`` replaced by ``calibration``; returns the
    new text and warnings (e.g. when comments could not be kept)."""
    doc = load_located(text, source)
    data = doc.data
    if not isinstance(data, dict) or device not in (data.get("devices") or {}):
        names = ", ".join((data or {}).get("devices") or {}) if isinstance(data, dict) else ""
        raise CalibrationWriteError(f"{source}: no device {device!r} in the profile "
                                    f"(devices: {names or 'none'})")
    newline = "\r\n" if "\r\n" in text else "\n"
    lines = text.splitlines()
    values = calibration_data(calibration)
    dev_key = doc.key_positions[("devices", device)]
    dev_value = doc.positions[("devices", device)]
    flow_device = dev_value[0] == dev_key[0] and \
        lines[dev_value[0] - 1][dev_value[1] - 1:].lstrip().startswith("{")
    if flow_device:
        return _full_dump(data, device, values), [
            f"devices.{device} is written in flow style ({{...}}); the profile was re-emitted "
            "in block style and its comments were lost (the old file is in the backup)"]
    new = _with_calibration_block(lines, doc, device, values)
    out = newline.join(new)
    return (out + newline if text.endswith(("\n", "\r")) or not text else out), []


def _with_calibration_block(lines: list[str], doc: Any, device: str,
                            values: dict[str, Any]) -> list[str]:
    """``lines`` (a block-style device) with its calibration block replaced, or added at
    the end of the device at its keys' indent; removed when ``values`` is empty."""
    cal_path = ("devices", device, "calibration")
    if cal_path in doc.key_positions:
        line, col = doc.key_positions[cal_path]
        start = line - 1
        end = _block_end(lines, start, col - 1)
        block = emit_block("calibration", values, col - 1) if values else []
        return lines[:start] + block + lines[end:]
    dev_key = doc.key_positions[("devices", device)]
    children = [pos for path, pos in doc.key_positions.items()
                if len(path) == 3 and path[:2] == ("devices", device)]
    col = min(c for _, c in children) - 1 if children else dev_key[1] - 1 + INDENT
    end = _block_end(lines, dev_key[0] - 1, dev_key[1] - 1)
    return lines[:end] + (emit_block("calibration", values, col) if values else []) + \
        lines[end:]


def _full_dump(data: dict[str, Any], device: str, values: dict[str, Any]) -> str:
    dev = dict(data["devices"][device])
    if values:
        dev["calibration"] = values
    else:
        dev.pop("calibration", None)
    data = {**data, "devices": {**data["devices"], device: dev}}
    return yaml.safe_dump(_plain(data), sort_keys=False, default_flow_style=None)


def _plain(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, datetime):
        return v.isoformat()
    return v


# --------------------------------------------------------------------------- writing
def write_device_calibration(path: str | Path, device: str, calibration: DeviceCalibration,
                             registry: Registry | None = None, *,
                             output: str | Path | None = None) -> tuple[Path | None, list[str]]:
    """Store ``calibration`` under ``devices.DEVICE`` of the profile at ``path`` (or, with
    ``output``, in a copy of it written there; ``path`` is then only read).

    The new text must load as a valid profile holding exactly ``calibration`` before it
    replaces the file. Returns (backup path, warnings).
    """
    p = Path(path)
    out = Path(output) if output is not None else p
    calibration = rounded(calibration)
    try:
        text = read_profile_text(p)
    except ProfileError as exc:
        raise CalibrationWriteError(f"{p}: cannot read the profile: "
                                    f"{'; '.join(exc.problems)}") from None
    new_text, warnings = replace_device_calibration(text, str(p), device, calibration)
    try:
        profile = parse_profile(new_text, str(out), registry)
    except Exception as exc:  # our own output must always load; refuse to write otherwise
        raise CalibrationWriteError(
            f"{out}: the rewritten profile would not load, so nothing was written: "
            f"{exc}") from None
    stored = profile.devices[device].calibration or DeviceCalibration()
    if calibration_data(stored) != calibration_data(calibration):
        raise CalibrationWriteError(
            f"{out}: the rewritten profile does not read back the calibration written, so "
            "nothing was written; please report this with the profile attached")
    try:
        bak = keep_backup(out)
        atomic_write_text(out, new_text)
    except (OSError, OutputError) as exc:
        raise CalibrationWriteError(f"{out}: could not write ({exc}); "
                                    f"{'the profile is' if out == p else 'nothing was'} "
                                    "unchanged") from None
    return bak, warnings
