"""Stream specs for a log: no chip to read back, so the rate is measured from time stamps.

``imuhal estimate`` binds its estimators (``Estimator.bind``) with the gyro stream measured
here, so the rule of live runs holds offline: a rate or period setting not given follows
the data, one given by hand that contradicts the measured rate by more than 5 % is an error
naming the option and the fix. No full scale is known (a log carries none): the limits keep
their defaults.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from imuhal.core.errors import ImuhalError
from imuhal.core.quantities import Quantity
from imuhal.core.samples import Frame, GyroSample, Sample
from imuhal.core.streams import StreamSpec, TimeSource
from imuhal.estimation.base import Estimator
from imuhal.estimation.streams import StreamContradiction
from imuhal.offline.csv_input import GYRO, TIME, SampleTable

LOG_DEVICE = "log"
"""The device name of a stream measured from a log."""


def measured_gyro_streams(times_s: np.ndarray) -> tuple[StreamSpec, ...]:
    """The gyro stream of rows stamped ``times_s`` (s): its rate is one over the median
    interval between increasing stamps (robust to a gap or a repeated row), measured on the
    whole nanoseconds the estimators see (so a log written with rounded seconds, 0.004 s
    apart, gives 250 Hz exactly, however many rows are measured). Empty when fewer than two
    intervals are there to measure."""
    t = np.asarray(times_s, dtype=float)
    t_ns = np.round(t[np.isfinite(t)] * 1e9).astype(np.int64)
    steps = np.diff(t_ns)
    steps = steps[steps > 0]
    if len(steps) < 2:
        return ()
    period_ns = round(float(np.median(steps)))
    return (StreamSpec(LOG_DEVICE, Quantity.GYRO, Frame.BODY_NED, 1e9 / period_ns,
                       time_source=TimeSource.LOG),)


def table_streams(table: SampleTable) -> tuple[StreamSpec, ...]:
    """The gyro stream of a wide CSV chunk (rows with a gyro reading)."""
    if not table.has(TIME, *GYRO):
        return ()
    has_gyro = np.isfinite(table.columns[GYRO[0]])
    return measured_gyro_streams(table.columns[TIME][has_gyro])


def sample_streams(samples: Iterable[Sample]) -> tuple[StreamSpec, ...]:
    """The gyro stream of a run log's samples."""
    times = [s.t_ns for s in samples if isinstance(s, GyroSample)]
    return measured_gyro_streams(np.asarray(times, dtype=float) * 1e-9)


def bind_to_log(estimator: Estimator, streams: tuple[StreamSpec, ...], option: str) -> None:
    """``estimator.bind(streams)``; a setting given with ``option`` (``--set``) that
    contradicts the measured rate is a one-line error naming it."""
    try:
        estimator.bind(streams)
    except StreamContradiction as exc:
        raise ImuhalError(f"{option} {exc.key}: {exc.problem} (the rate measured from the "
                          "log's time stamps)") from None
