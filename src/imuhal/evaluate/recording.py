"""Recordings with ground truth, in one form whatever their source.

A :class:`Recording` holds IMU samples in imuhal's body NED frame (gyro rad/s, accelerometer
specific force m/s^2, magnetometer uT), the true body -> NED quaternion on the same rows and
the mask of rows to evaluate. Readers:

- BROAD trials (Laidig et al. 2021), HDF5 or MAT: ``imu_gyr``, ``imu_acc``, ``imu_mag`` in the
  sensor's axes, ``opt_quat`` (sensor -> ENU, already aligned to the IMU's earth frame by the
  dataset), ``movement`` (BROAD's evaluation mask) and the sampling rate. The accelerometer is
  specific force (at rest it reads +9.81 m/s^2 up), so the sensor axes are read as imuhal's
  ``enu`` convention (forward-left-up body) and converted exactly; the truth goes through the
  same conversion, so errors are unchanged by it. Groups come from the ``trials.json`` next
  to the file.
- imuhal's own sample CSV (``imuhal estimate`` input, any ``--input-frame``) plus a truth CSV
  (``imuhal run --truth``: ``t_s, qw, qx, qy, qz`` body -> NED): the truth is interpolated
  (normalised linear, sign-continuous) at the sample times; rows outside the truth's time
  span are not evaluated. The sample CSV may also be a run log (``imuhal run --output LOG.csv
  --samples``, as ``imuhal estimate`` reads it): its valid samples become rows at the IMU's
  gyro times, each with the IMU's accelerometer sample of that time (else its latest before)
  and a magnetometer sample on the first row at or after it, as the pipeline fused them.

Loading needs h5py (HDF5) or scipy (MAT): ``pip install imuhal[eval]``.
"""

from __future__ import annotations

import csv
import importlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imuhal.core.conventions import ENU, NED, Convention, VectorKind, convert_quat, vector_to_ned
from imuhal.core.errors import ImuhalError
from imuhal.core.frames import FloatArray
from imuhal.core.samples import AccelSample, GyroSample, MagSample
from imuhal.offline.csv_input import ACCEL, GYRO, MAG, TIME, read_sample_csv, require
from imuhal.offline.frames import resolve_input_frame, table_to_ned
from imuhal.offline.run_log import is_run_log, read_run_log

BROAD_SUFFIXES = (".hdf5", ".h5", ".mat")


class RecordingError(ImuhalError):
    """A recording cannot be read; the message names the file and the fix."""


@dataclass
class Recording:
    """Samples and truth on the same rows (body NED, SI units)."""

    name: str
    t_s: FloatArray
    gyro_rad_s: FloatArray
    accel_m_s2: FloatArray
    mag_ut: FloatArray | None
    """(N, 3), NaN on rows without a magnetometer sample; None: no magnetometer."""
    q_truth: FloatArray
    """(N, 4) body -> NED."""
    mask: np.ndarray
    """(N,) bool: the rows the errors are taken over."""
    rate_hz: float
    groups: tuple[str, ...] = field(default=())

    def __len__(self) -> int:
        return len(self.t_s)


@dataclass(frozen=True)
class RecordingSource:
    """Where a recording comes from (cheap to send to a Dask worker, which loads it)."""

    path: str
    truth: str | None = None
    """The truth CSV, for an imuhal sample CSV."""
    input_frame: str | None = None
    """Convention of an imuhal sample CSV's vectors (None: the columns' suffix, else ned)."""

    @property
    def name(self) -> str:
        return Path(self.path).stem

    def load(self) -> Recording:
        p = Path(self.path)
        if p.suffix.lower() in BROAD_SUFFIXES:
            return read_broad(p)
        if p.suffix.lower() == ".csv":
            if self.truth is None:
                raise RecordingError(f"{p}: a sample CSV needs its truth CSV; give --truth "
                                     "TRUTH.csv (from `imuhal run --truth`)")
            return read_csv_recording(p, self.truth, self.input_frame)
        raise RecordingError(f"{p}: unknown recording type; give a BROAD .hdf5/.mat trial or an "
                             "imuhal sample .csv with --truth")


def _need(module: str) -> Any:
    try:
        return importlib.import_module(module)
    except ImportError:
        raise RecordingError(f"reading this file needs {module}: pip install "
                             "'imuhal[eval]'") from None


def _broad_arrays(path: Path) -> dict[str, np.ndarray]:
    if not path.is_file():
        raise RecordingError(f"{path}: no such file")
    if path.suffix.lower() == ".mat":
        sio = _need("scipy.io")
        try:
            raw = sio.loadmat(str(path))
        except Exception as exc:  # scipy raises several types for a damaged file
            raise RecordingError(f"{path}: not a readable MAT file ({exc})") from None
        data = {k: np.asarray(v) for k, v in raw.items() if not k.startswith("__")}
        data["sampling_rate"] = np.asarray(data.get("sampling_rate", np.nan)).reshape(())
    else:
        h5py = _need("h5py")
        try:
            with h5py.File(path, "r") as f:
                data = {k: f[k][()] for k in f}
                data["sampling_rate"] = np.asarray(f.attrs.get("sampling_rate", np.nan))
        except OSError as exc:
            raise RecordingError(f"{path}: not a readable HDF5 file ({exc})") from None
    missing = [k for k in ("imu_gyr", "imu_acc", "opt_quat", "movement") if k not in data]
    if missing:
        raise RecordingError(f"{path}: missing {', '.join(missing)}; not a BROAD trial")
    return data


def broad_groups(path: Path) -> tuple[str, ...]:
    """The trial's groups from the ``trials.json`` next to it (empty if there is none)."""
    index = path.parent / "trials.json"
    if not index.is_file():
        return ()
    try:
        info = json.loads(index.read_text(encoding="utf-8"))
        return tuple(info["trials"][path.stem]["groups"])
    except (KeyError, ValueError, TypeError):
        return ()


def read_broad(path: str | Path) -> Recording:
    """One BROAD trial (HDF5 or MAT) in imuhal's frames (module docstring)."""
    p = Path(path)
    d = _broad_arrays(p)
    rate = float(d["sampling_rate"])
    if not np.isfinite(rate) or rate <= 0:
        raise RecordingError(f"{p}: no valid sampling_rate")
    gyro = vector_to_ned(np.asarray(d["imu_gyr"], float), ENU, VectorKind.ANGULAR_RATE)
    accel = vector_to_ned(np.asarray(d["imu_acc"], float), ENU, VectorKind.SPECIFIC_FORCE)
    mag = (vector_to_ned(np.asarray(d["imu_mag"], float), ENU, VectorKind.MAGNETIC_FIELD)
           if "imu_mag" in d else None)
    truth = convert_quat(np.asarray(d["opt_quat"], float), ENU, NED)
    mask = np.asarray(d["movement"]).reshape(-1).astype(bool)
    n = len(gyro)
    if accel.shape != (n, 3) or truth.shape != (n, 4) or mask.shape != (n,):
        raise RecordingError(f"{p}: imu_gyr, imu_acc, opt_quat and movement differ in length")
    return Recording(name=p.stem, t_s=np.arange(n) / rate, gyro_rad_s=gyro, accel_m_s2=accel,
                     mag_ut=mag, q_truth=truth, mask=mask, rate_hz=rate, groups=broad_groups(p))


def read_truth_quaternions(path: str | Path) -> tuple[FloatArray, FloatArray]:
    """``t_s`` and the body -> NED quaternion columns of an imuhal truth CSV."""
    p = Path(path)
    try:
        lines = [ln for ln in p.read_text(encoding="utf-8").splitlines()
                 if ln.strip() and not ln.startswith("#")]
    except OSError as exc:
        raise RecordingError(f"{p}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise RecordingError(f"{p}: not a text file; a truth CSV is written by `imuhal run "
                             "--truth`") from None
    try:
        rows = list(csv.reader(lines))
    except csv.Error as exc:  # a cell over the csv module's field limit, a NUL byte
        raise RecordingError(f"{p}: not CSV text ({exc}); a truth CSV is written by "
                             "`imuhal run --truth`") from None
    if len(rows) < 2:
        raise RecordingError(f"{p}: no truth rows; expected a header and t_s, qw, qx, qy, qz")
    header = [h.strip() for h in rows[0]]
    cols = ("t_s", "qw", "qx", "qy", "qz")
    missing = [c for c in cols if c not in header]
    if missing:
        raise RecordingError(f"{p}: missing column(s) {', '.join(missing)}; a truth CSV from "
                             "`imuhal run --truth` has them")
    idx = [header.index(c) for c in cols]
    try:
        data = np.array([[float(r[i]) for i in idx] for r in rows[1:]])
    except (ValueError, IndexError):
        raise RecordingError(f"{p}: a truth row is not numeric or is short") from None
    return data[:, 0], data[:, 1:]


def interpolate_quaternions(t_src: FloatArray, q_src: FloatArray, t: FloatArray) -> FloatArray:
    """Normalised linear interpolation of a sign-continuous quaternion track at ``t``
    (NaN outside ``t_src``'s span)."""
    q = np.array(q_src, dtype=float)
    flips = np.cumsum(np.r_[False, np.sum(q[1:] * q[:-1], axis=1) < 0]) % 2 == 1
    q[flips] *= -1
    out = np.stack([np.interp(t, t_src, q[:, k]) for k in range(4)], axis=1)
    out /= np.linalg.norm(out, axis=1)[:, None]
    out[(t < t_src[0]) | (t > t_src[-1])] = np.nan
    return out


def read_csv_recording(samples: str | Path, truth: str | Path,
                       input_frame: str | Convention | None = None) -> Recording:
    """An imuhal sample CSV (as ``imuhal estimate`` reads it) with its truth CSV."""
    from imuhal.core.conventions import get_convention

    requested = None if input_frame is None else get_convention(input_frame)
    if is_run_log(samples):
        t, gyro, accel, mag = run_log_rows(samples, requested)
    else:
        table, frame = resolve_input_frame(read_sample_csv(samples), requested)
        table = table_to_ned(table, frame)
        require(table, (TIME, *GYRO, *ACCEL), "evaluation")
        c = table.columns
        t = np.asarray(c[TIME], float)
        gyro = np.stack([c[n] for n in GYRO], axis=1)
        accel = np.stack([c[n] for n in ACCEL], axis=1)
        mag = np.stack([c[n] for n in MAG], axis=1) if table.has(*MAG) else None
    t_truth, q_truth = read_truth_quaternions(truth)
    q = interpolate_quaternions(t_truth, q_truth, t)
    rate = float(1.0 / np.median(np.diff(t))) if len(t) > 1 else 1.0
    return Recording(name=Path(samples).stem, t_s=t, gyro_rad_s=gyro, accel_m_s2=accel,
                     mag_ut=mag, q_truth=q, mask=~np.isnan(q[:, 0]), rate_hz=rate)


def run_log_rows(path: str | Path, frame: Convention | None = None
                 ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]:
    """A run log's valid IMU samples as rows: times (s), gyro, accel and magnetometer (NaN on
    rows without one; None when the log has none), body NED."""
    log = read_run_log(path, frame)
    gyros = [s for s in log.samples if isinstance(s, GyroSample)]
    devices = list(dict.fromkeys(s.device for s in gyros))
    if len(devices) != 1:
        raise RecordingError(f"{path}: the run log has valid gyro samples from "
                             f"{len(devices)} devices ({', '.join(devices) or 'none'}); "
                             "evaluation reads a log of one IMU")
    imu = devices[0]
    accels = [s for s in log.samples if isinstance(s, AccelSample) and s.device == imu]
    if not accels:
        raise RecordingError(f"{path}: no valid accelerometer samples from {imu}")
    gyro_t = np.array([s.t_ns for s in gyros], dtype=np.int64)
    accel_t = np.array([s.t_ns for s in accels], dtype=np.int64)
    # The accelerometer sample of the gyro's instant, else the latest before it.
    which = np.searchsorted(accel_t, gyro_t, side="right") - 1
    keep = which >= 0
    gyro_t, which = gyro_t[keep], which[keep]
    gyro = np.array([s.gyro_rad_s for s in gyros], dtype=float)[keep]
    accel = np.array([s.accel_m_s2 for s in accels], dtype=float)[which]
    mags = [s for s in log.samples if isinstance(s, MagSample)]
    mag = None
    if mags:
        mag = np.full((len(gyro_t), 3), np.nan)
        rows = np.searchsorted(gyro_t, [s.t_ns for s in mags], side="left")
        for row, sample in zip(rows, mags, strict=True):
            if row < len(gyro_t):  # fused with the next gyro update, as in the pipeline
                mag[row] = sample.mag_ut
    return gyro_t / 1e9, gyro, accel, mag
