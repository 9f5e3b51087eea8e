"""Scripted mutation testing, run on demand (not part of the test suite).

    .venv/bin/python tests/mutation/run_mutations.py            # every mutation
    .venv/bin/python tests/mutation/run_mutations.py --only F1 M2
    .venv/bin/python tests/mutation/run_mutations.py --list
    .venv/bin/python tests/mutation/run_mutations.py --check   # every mutation still applies

Each mutation is one deliberate mistake of the kind a reviewer worries about (a wrong sign,
a swapped axis, a wrong datasheet fact) in drivers, pipeline processing, calibration and
frames. For each, the repository is copied to a temporary directory, the mistake applied to
the copy (the working tree is never touched), and the tests named for it run there with the
copy first on the import path. A mutation is *killed* when a test fails and *survives* when
every test passes; the first failing test is reported. mutmut was not used: it rewrites the
installed tree in place and mutates every operator of every line, which on this layout
takes hours for mostly equivalent mutants; a short list of meaningful mistakes runs in
minutes.

The shared-fact mutations (F*) run without the datasheet-vector tests, so a kill there shows
that a driver-against-emulator test catches the wrong fact. Results are summarised in
docs/architecture.md ("Mutation testing").
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

CHIPS = "tests/chips"
FRAMES = ("tests/integration/test_frame_truth.py",)
PIPELINE = ("tests/pipeline", "tests/integration", "tests/core")
CALIBRATION = ("tests/calibration", "tests/pipeline")


@dataclass(frozen=True)
class Mutation:
    id: str
    what: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]
    occurrence: int = 1
    """Which occurrence of ``old`` to replace (1 = first)."""


def _driver_vs_emulator(*files: str) -> tuple[str, ...]:
    return (*files, "tests/chips/test_conformance_sweep.py")


MUTATIONS: tuple[Mutation, ...] = (
    # -- the three mount mistakes of issue 16 item 4 -----------------------------------------
    Mutation("M1", "seed profile IMU mount -Y-X-Z written as -X+Y-Z (still a rotation)",
             "profiles/seed-paraglider-vario.yaml", 'mount: "-Y-X-Z"', 'mount: "-X+Y-Z"',
             FRAMES),
    Mutation("M2", "pipeline chip-to-body rotation swaps body x and y",
             "src/imuhal/profile/topology.py",
             "{n: board_to_body @ parse_mount(d.mount)",
             "{n: [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]] @ board_to_body "
             "@ parse_mount(d.mount)", FRAMES),
    Mutation("M3", "mount and board_to_body composed in the wrong order (pipeline)",
             "src/imuhal/profile/topology.py",
             "board_to_body @ parse_mount(d.mount)", "parse_mount(d.mount) @ board_to_body",
             FRAMES),
    Mutation("M4", "mount and board_to_body composed in the wrong order (emulated board)",
             "src/imuhal/emulation/mounting.py",
             "_product(board, _matrix(dev.mount))", "_product(_matrix(dev.mount), board)",
             FRAMES),
    # (Inverting every sign the emulated board reads is an equivalent mutant: each matrix
    # becomes its negative and board_to_body @ mount = (-B) @ (-M) is unchanged.)
    Mutation("M5", "emulated board ignores the signs of a mount string",
             "src/imuhal/emulation/mounting.py",
             "row[_AXIS_INDEX[ch]] = sign", "row[_AXIS_INDEX[ch]] = 1.0", FRAMES),
    # -- the four shared-fact mistakes of issue 16 item 3 (no datasheet-vector tests) --------
    Mutation("F1", "MS5611 driver: wrong sign of the C4 (TCO) offset term",
             "plugins/imuhal_chips/ms5611/conversion.py",
             "off = (c.c2 << 16) + ((c.c4 * dt) >> 7)", "off = (c.c2 << 16) - ((c.c4 * dt) >> 7)",
             _driver_vs_emulator(
                 "tests/chips/test_ms5611_driver.py",
                 "tests/chips/test_ms5611_conversion.py::"
                 "test_driver_compensates_emulator_counts_to_the_truth")),
    Mutation("F2", "MS5611 driver: CRC-4 polynomial x^4 + x^2 + 1 instead of x^4 + x + 1",
             "plugins/imuhal_chips/ms5611/conversion.py",
             "remainder = ((remainder << 1) ^ 0x3000) & 0xFFFF",
             "remainder = ((remainder << 1) ^ 0x5000) & 0xFFFF",
             _driver_vs_emulator(
                 "tests/chips/test_ms5611_driver.py",
                 "tests/chips/test_ms5611_conversion.py::"
                 "test_driver_and_emulator_crc4_agree_on_random_proms")),
    Mutation("F3", "MAX2110x driver: gyro sensitivity at 500 dps 65.5 instead of 60 LSB/dps",
             "plugins/imuhal_chips/max2110x/registers.py",
             "500: (0b10, 60.0),", "500: (0b10, 65.5),",
             _driver_vs_emulator("tests/chips/test_max2110x_driver.py")),
    Mutation("F4", "AK8963 driver: ASA adjustment without the 0.5 factor",
             "plugins/imuhal_chips/ak8963/decode.py",
             "return (asa + 128) / 256.0", "return (asa - 128) / 128.0 + 1.0",
             _driver_vs_emulator("tests/chips/test_ak8963_driver.py",
                                 "tests/chips/test_mpu9250_driver.py")),
    # -- drivers -------------------------------------------------------------------------------
    Mutation("D1", "HMC5883L driver: data registers read as X, Y, Z (they are X, Z, Y)",
             "plugins/imuhal_chips/hmc5883l/decode.py",
             "y = int.from_bytes(data[4:6]", "y = int.from_bytes(data[2:4]", (CHIPS,)),
    Mutation("D2", "AK8963 driver: data read big-endian",
             "plugins/imuhal_chips/ak8963/decode.py",
             'x, y, z = struct.unpack("<hhh"', 'x, y, z = struct.unpack(">hhh"', (CHIPS,)),
    Mutation("D3", "MPU-9250 driver: gyro in deg/s instead of rad/s",
             "plugins/imuhal_chips/mpu9250/decode.py",
             "k = math.radians(1.0) / lsb_per_dps", "k = 1.0 / lsb_per_dps", (CHIPS,)),
    Mutation("D4", "MPU-9250 driver: room-temperature offset subtracted",
             "plugins/imuhal_chips/mpu9250/decode.py",
             "return count / TEMP_LSB_PER_DEGC + TEMP_OFFSET_DEGC",
             "return count / TEMP_LSB_PER_DEGC - TEMP_OFFSET_DEGC", (CHIPS,)),
    Mutation("D5", "MPU-9250 driver: 4 g range with the 8 g sensitivity",
             "plugins/imuhal_chips/mpu9250/registers.py",
             "4: Range(1, 8192.0)", "4: Range(1, 4096.0)", (CHIPS,)),
    Mutation("D6", "MS5611 driver: second-order OFF2 divided by 4 instead of 2",
             "plugins/imuhal_chips/ms5611/conversion.py",
             "off2 = (5 * low) >> 1", "off2 = (5 * low) >> 2", (CHIPS,)),
    Mutation("D7", "BMP280 driver: 64-bit pressure P8 term shifted by 18 instead of 19",
             "plugins/imuhal_chips/bmp280/compensation.py",
             "var2 = (trim.P8 * p) >> 19", "var2 = (trim.P8 * p) >> 18", (CHIPS,)),
    Mutation("D8", "MAX2110x driver: accelerometer 4 g sensitivity 7000 instead of 7500 LSB/g",
             "plugins/imuhal_chips/max2110x/registers.py",
             "4: (0b10, 7500.0),", "4: (0b10, 7000.0),", (CHIPS,)),
    Mutation("D9", "BMP280 driver: xlsb nibble dropped from the 20-bit pressure",
             "plugins/imuhal_chips/bmp280/compensation.py",
             "press = (data[0] << 12) | (data[1] << 4) | (data[2] >> 4)",
             "press = (data[0] << 12) | (data[1] << 4)", (CHIPS,)),
    # -- driver timing facts (the emulators keep their own rate and timing tables) -------------
    Mutation("T1", "MPU-9250 driver: DLPF 41 Hz assumed to sample at 8 kHz (it is 1 kHz)",
             "plugins/imuhal_chips/mpu9250/registers.py",
             "41: GyroFilter(3, 1000)", "41: GyroFilter(3, 8000)", (CHIPS,)),
    Mutation("T2", "HMC5883L driver: 75 Hz written as the 30 Hz code",
             "plugins/imuhal_chips/hmc5883l/registers.py",
             "30: 5, 75: 6,", "30: 5, 75: 5,", (CHIPS,)),
    Mutation("T3", "MAX21100 driver: gyro ODR codes shifted by one",
             "plugins/imuhal_chips/max2110x/registers.py",
             "(8000, 4000, 2000, 1000, 500, 250, 125, 62.5, 31.25, 15.625, 7.8125, 3.90625)",
             "(4000, 2000, 1000, 500, 250, 125, 62.5, 31.25, 15.625, 7.8125, 3.90625, 1.953125)",
             (CHIPS,)),
    Mutation("T4", "MS5611 driver: OSR 4096 conversion assumed to take 4.13 ms (typ 8.22)",
             "plugins/imuhal_chips/ms5611/commands.py",
             "4096: OsrTiming(4096, 4, 7.40, 8.22, 9.04)",
             "4096: OsrTiming(4096, 4, 3.72, 4.13, 4.54)", (CHIPS,)),
    # -- pipeline processing -------------------------------------------------------------------
    Mutation("P1", "processing: NaN/inf check disabled",
             "src/imuhal/pipeline/processing.py",
             "if not all(map(math.isfinite, values)):", "if False:", PIPELINE),
    Mutation("P2", "processing: chip-to-body rotation applied transposed",
             "src/imuhal/pipeline/processing.py",
             "return (0.0 + a * x + b * y + c * z, 0.0 + d * x + e * y + f * z,\n"
             "            0.0 + g * x + h * y + i * z)",
             "return (0.0 + a * x + d * y + g * z, 0.0 + b * x + e * y + h * z,\n"
             "            0.0 + c * x + f * y + i * z)", PIPELINE),
    Mutation("P3", "processing: gyro samples corrected with the accelerometer record",
             "src/imuhal/pipeline/processing.py",
             "return calibration.gyro", "return calibration.accel", CALIBRATION),
    Mutation("P4", "processing: calibration skipped before the rotation",
             "src/imuhal/pipeline/processing.py",
             "vector = sample.vector if record is None else record.apply(sample.vector)",
             "vector = sample.vector", CALIBRATION),
    # -- calibration model ---------------------------------------------------------------------
    Mutation("C1", "calibration: inertial offset added instead of subtracted (x axis)",
             "src/imuhal/calibration/model.py",
             "((raw[0] - offset[0]) * scale[0]", "((raw[0] + offset[0]) * scale[0]",
             CALIBRATION),
    Mutation("C2", "calibration: hard iron added instead of subtracted (x axis)",
             "src/imuhal/calibration/model.py",
             "(raw[0] - h[0], raw[1] - h[1], raw[2] - h[2])",
             "(raw[0] + h[0], raw[1] - h[1], raw[2] - h[2])", CALIBRATION),
    Mutation("C3", "calibration: correction matrix row 0 read as a column",
             "src/imuhal/calibration/model.py",
             "m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],",
             "m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],", CALIBRATION),
    Mutation("C4", "calibration: scale applied before the offset is removed (x axis)",
             "src/imuhal/calibration/model.py",
             "((raw[0] - offset[0]) * scale[0]", "(raw[0] * scale[0] - offset[0]",
             CALIBRATION),
    # -- frames --------------------------------------------------------------------------------
    Mutation("R1", "frames: Hamilton product x term with the cross product reversed",
             "src/imuhal/core/frames.py",
             "pw * qx + px * qw + py * qz - pz * qy,", "pw * qx + px * qw - py * qz + pz * qy,",
             ("tests/core", *FRAMES)),
    Mutation("R2", "frames: signed-axis mount strings read as columns instead of rows",
             "src/imuhal/core/frames.py",
             'm[row, "XYZ".index(axis.upper())]', 'm["XYZ".index(axis.upper()), row]',
             ("tests/core", *FRAMES)),
    Mutation("R3", "frames: roll from the quaternion with the y*z term's sign flipped",
             "src/imuhal/core/frames.py",
             "roll = math.atan2(2 * (w * x + y * z)", "roll = math.atan2(2 * (w * x - y * z)",
             ("tests/core", "tests/filters")),
    # -- GNSS receiver and flight-app output ---------------------------------------------------
    Mutation("G1", "GNSS driver: NMEA speed read as m/s (it is knots)",
             "plugins/imuhal_chips/gnss/decode.py",
             "KNOT_M_S = 1852.0 / 3600.0", "KNOT_M_S = 1.0",
             ("tests/chips/test_gnss_decode.py", "tests/chips/test_gnss_driver.py")),
    Mutation("G2", "GNSS driver: NAV-PVT velocity in cm/s (it is mm/s)",
             "plugins/imuhal_chips/gnss/decode.py",
             "frag.velocity_ned_m_s = (int(msg.velN) / 1000.0,",
             "frag.velocity_ned_m_s = (int(msg.velN) / 100.0,",
             ("tests/chips/test_gnss_decode.py", "tests/chips/test_gnss_driver.py")),
    Mutation("G3", "GNSS driver: a sentence with a wrong checksum merged into the fix",
             "plugins/imuhal_chips/gnss/driver.py",
             "        if not frag.checksum_ok:\n            self.stats.checksum_errors += 1",
             "        if False:\n            self.stats.checksum_errors += 1",
             ("tests/chips/test_gnss_driver.py",)),
    Mutation("G4", "LK8EX1 vario in dm/s (it is cm/s)",
             "src/imuhal/sinks/flight/sentences.py",
             "str(round(climb_m_s * 100.0))", "str(round(climb_m_s * 10.0))",
             ("tests/sinks",)),
    Mutation("G5", "POV pressure in Pa (it is hPa)",
             "src/imuhal/sinks/flight/sentences.py",
             'parts += ["P", f"{pressure_pa / 100.0:.2f}"]', 'parts += ["P", f"{pressure_pa:.2f}"]',
             ("tests/sinks",)),
    Mutation("G6", "NMEA latitude minutes written as decimal degrees",
             "src/imuhal/sinks/flight/sentences.py",
             "    minutes = (a - deg) * 60.0\n    if round(minutes, 4) >= 60.0:  # 59.99999",
             "    minutes = (a - deg) * 100.0\n    if round(minutes, 4) >= 60.0:  # 59.99999",
             ("tests/sinks",)),
    Mutation("G7", "vario audio: beep cadence table read from the slow end for strong climbs",
             "src/imuhal/sinks/flight/audio.py",
             "index = min(max(int(climb_m_s), 0), len(BEEP_TABLE_TICKS) - 1)",
             "index = 0", ("tests/sinks/test_vario_audio.py",)),
    Mutation("G8", "LXWP0 vario in cm/s (it is m/s)",
             "src/imuhal/sinks/flight/sentences.py",
             '_fmt(climb_m_s, ".2f"), "", "", "", "", "",',
             '_fmt(None if climb_m_s is None else climb_m_s * 100, ".2f"), "", "", "", "", "",',
             ("tests/sinks",)),
    Mutation("I1", "IGC: the G record hashes the records before the new one",
             "src/imuhal/sinks/flight/igc.py",
             '        self._sha.update(records)\n        g = b"G" + self._sha.hexdigest()',
             '        old = self._sha.copy()\n        self._sha.update(records)\n'
             '        g = b"G" + old.hexdigest()',
             ("tests/sinks/test_igc_log.py",)),
)


def _copy_tree(dest: Path) -> None:
    ignore = shutil.ignore_patterns(".venv", ".git", "__pycache__", "*.egg-info",
                                    ".pytest_cache", ".ruff_cache")
    shutil.copytree(ROOT, dest, symlinks=True, ignore=ignore)


def _apply(root: Path, m: Mutation) -> None:
    path = root / m.path
    text = path.read_text()
    count = text.count(m.old)
    if count < m.occurrence:
        raise SystemExit(f"{m.id}: {m.path} no longer contains {m.old!r} "
                         f"(occurrence {m.occurrence}); update the mutation list")
    start = -1
    for _ in range(m.occurrence):
        start = text.index(m.old, start + 1)
    path.write_text(text[:start] + m.new + text[start + len(m.old):])


def _env(root: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(root / "src"), str(root / "plugins"), str(root)])
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


def _imports_from(root: Path) -> bool:
    """True when the copy's packages, not the installed ones, are what Python imports."""
    out = subprocess.run(
        [sys.executable, "-c", "import imuhal, imuhal_chips, imuhal_filters; print("
         "imuhal.__file__); print(imuhal_chips.__file__); print(imuhal_filters.__file__)"],
        cwd=root, env=_env(root), capture_output=True, text=True).stdout.split()
    return len(out) == 3 and all(Path(p).is_relative_to(root) for p in out)


def _pytest(root: Path, tests: tuple[str, ...]) -> tuple[int, str]:
    env = _env(root)
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", "-rf",
         "-W", "ignore::pytest.PytestAssertRewriteWarning", *tests],
        cwd=root, env=env, capture_output=True, text=True)
    failed = [line.split(" ", 1)[1].split(" - ")[0]
              for line in proc.stdout.splitlines() if line.startswith("FAILED ")]
    errors = [line for line in proc.stdout.splitlines() if line.startswith("ERROR ")]
    return proc.returncode, (failed or errors or [proc.stdout.strip().splitlines()[-1:]])[0] \
        if proc.returncode else ""


def run(mutations: list[Mutation]) -> int:
    with tempfile.TemporaryDirectory(prefix="imuhal-mut-") as tmp:
        base = Path(tmp) / "base"
        _copy_tree(base)
        # The copy must be what the tests import, and must pass unmutated.
        if not _imports_from(base):
            print("the copy's packages do not shadow the installed ones", file=sys.stderr)
            return 2
        code, first = _pytest(base, ("tests/core/test_frames.py",))
        if code:
            print(f"baseline fails in the copy ({first}); fix that first", file=sys.stderr)
            return 2
        survived = 0
        for m in mutations:
            work = Path(tmp) / m.id
            shutil.copytree(base, work, symlinks=True)
            _apply(work, m)
            started = time.monotonic()
            code, first = _pytest(work, m.tests)
            took = time.monotonic() - started
            verdict = "killed" if code else "SURVIVED"
            survived += not code
            print(f"{m.id:3} {verdict:8} {took:5.1f} s  {m.what}"
                  + (f"\n              by {first}" if code else ""), flush=True)
            shutil.rmtree(work)
        total = len(mutations)
        print(f"\nscore: {total - survived}/{total} killed")
        return 1 if survived else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", metavar="ID", help="run only these mutations")
    parser.add_argument("--list", action="store_true", help="list the mutations and exit")
    parser.add_argument("--check", action="store_true",
                        help="check that every mutation still applies to the tree, run nothing")
    args = parser.parse_args()
    chosen = [m for m in MUTATIONS if not args.only or m.id in args.only]
    if args.list:
        for m in chosen:
            print(f"{m.id:3} {m.path}: {m.what}")
        return 0
    if args.check:
        stale = [m for m in chosen
                 if (ROOT / m.path).read_text().count(m.old) < m.occurrence]
        for m in stale:
            print(f"{m.id}: {m.path} no longer contains {m.old!r}", file=sys.stderr)
        return 1 if stale else 0
    unknown = set(args.only or ()) - {m.id for m in MUTATIONS}
    if unknown:
        print(f"unknown mutation ids: {', '.join(sorted(unknown))}", file=sys.stderr)
        return 2
    return run(chosen)


if __name__ == "__main__":
    sys.exit(main())
