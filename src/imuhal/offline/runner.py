"""Feeding a sample table through any registered estimator, as the pipeline would.

An IMU table becomes blocks (imuhal.core.blocks: one per column group, body frame, project
units) routed by the pipeline's own router (imuhal.pipeline.router), so an estimator
behaves identically live and offline: the frames reach it in time order and, within a row,
in the pipeline's fusion order (imuhal.estimation.ordering: accelerometer, magnetometer,
pressure, then gyro), so an AHRS stepping on the gyro uses that row's accel and mag, as it
does live; an AHRS takes a chunk's blocks at once (``update_blocks``: its compiled row
kernel). Other tables (a vario's altitude and upward acceleration) become the same sample
and estimate objects the pipeline produces.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence

import numpy as np

from imuhal.core.atmosphere import SEA_LEVEL_PRESSURE_PA, pressure_pa_at_altitude
from imuhal.core.blocks import Block
from imuhal.core.frames import IDENTITY_QUATERNION
from imuhal.core.samples import (
    AccelSample,
    Frame,
    GyroSample,
    MagSample,
    PressureSample,
    Sample,
)
from imuhal.estimation.base import Estimator
from imuhal.estimation.outputs import AttitudeEstimate, Estimate, checked_estimates
from imuhal.estimation.rows import AttitudeRows, RowsEstimator
from imuhal.offline.chain import EstimatorChain, instants_in_fusion_order
from imuhal.offline.csv_input import (
    ACCEL,
    ACCEL_UP,
    ALTITUDE,
    GYRO,
    MAG,
    PRESSURE,
    TIME,
    InputError,
    SampleTable,
    require,
)
from imuhal.pipeline.router import Router

DEVICE = "input"


def imu_events(table: SampleTable) -> Iterator[Sample]:
    """Each row's accel, mag (when present on the row), pressure (idem) and gyro samples, in
    fusion order (the CSV reader has already refused non-finite values)."""
    require(table, (TIME, *GYRO, *ACCEL), "an attitude estimator")
    c = table.columns
    # The yield order below is the fusion order (imuhal.estimation.ordering.FUSION_RANK:
    # accelerometer, magnetometer, pressure, then gyro), written out for speed.
    # plain Python floats (not numpy scalars) row by row: what a driver hands the pipeline,
    # and several times cheaper for the per-sample arithmetic downstream
    t_ns_list = [round(t * 1e9) for t in c[TIME].tolist()]
    gyro = zip(*(c[n].tolist() for n in GYRO), strict=True)
    accel = zip(*(c[n].tolist() for n in ACCEL), strict=True)
    mag = zip(*(c[n].tolist() for n in MAG), strict=True) if table.has(*MAG) else None
    pressure = c[PRESSURE].tolist() if table.has(PRESSURE) else None
    for i, (t_ns, g, a) in enumerate(zip(t_ns_list, gyro, accel, strict=True)):
        yield AccelSample(t_ns=t_ns, device=DEVICE, frame=Frame.BODY_NED, accel_m_s2=a)
        if mag is not None:
            m = next(mag)
            if not math.isnan(m[0]):
                yield MagSample(t_ns=t_ns, device=DEVICE, frame=Frame.BODY_NED, mag_ut=m)
        if pressure is not None and not math.isnan(pressure[i]):
            yield PressureSample(t_ns=t_ns, device=DEVICE, pressure_pa=pressure[i])
        yield GyroSample(t_ns=t_ns, device=DEVICE, frame=Frame.BODY_NED, gyro_rad_s=g)


def imu_blocks(table: SampleTable) -> list[Block]:
    """The samples :func:`imu_events` makes of ``table``, as one block per quantity (the
    accelerometer, the magnetometer and pressure on the rows that carry them, the gyro):
    one fusion step, in time order (the CSV reader has refused times that do not
    increase)."""
    require(table, (TIME, *GYRO, *ACCEL), "an attitude estimator")
    c = table.columns
    t_ns = np.round(c[TIME] * 1e9).astype(np.int64)

    def block(kind: type[Sample], names: tuple[str, ...], rows: np.ndarray | None = None
              ) -> Block | None:
        values = np.stack([c[n] for n in names], axis=1)
        t = t_ns
        if rows is not None:
            if not rows.any():
                return None
            values, t = values[rows], t_ns[rows]
        return Block.from_arrays(kind, DEVICE, int(t[0]), t - t[0], values,
                                 np.zeros(len(t), np.int64),
                                 frame=Frame.BODY_NED if len(names) == 3 else None)

    blocks = [block(AccelSample, ACCEL)]
    if table.has(*MAG):
        blocks.append(block(MagSample, MAG, ~np.isnan(c[MAG[0]])))
    if table.has(PRESSURE):
        blocks.append(block(PressureSample, (PRESSURE,), ~np.isnan(c[PRESSURE])))
    blocks.append(block(GyroSample, GYRO))
    return [b for b in blocks if b is not None]


def fuse_table(estimators: Sequence[Estimator], table: SampleTable) -> list[Estimate]:
    """Every estimate the chain of ``estimators`` (profile order, each taking every source)
    makes of an IMU table's blocks (:func:`imu_blocks`), through the pipeline's router."""
    out: list[Estimate] = []
    blocks = imu_blocks(table)
    if blocks and len(blocks[0]):
        Router.of(estimators).fuse_blocks(blocks, out)
    return out


def vario_events(table: SampleTable, sea_level_pa: float) -> Iterator[Sample | Estimate]:
    """From ``t_s, altitude_m, accel_up_m_s2``: the gravity-compensated acceleration as a
    level attitude estimate carrying it, then the altitude as the pressure that reads it.
    Either cell may be empty (a multi-rate log): only what the row carries is fed."""
    require(table, (TIME, ALTITUDE), "a vario filter")
    c = table.columns
    has_accel = ACCEL_UP in c
    for i in range(len(table)):
        t_ns = round(float(c[TIME][i]) * 1e9)
        if has_accel and not math.isnan(c[ACCEL_UP][i]):
            yield AttitudeEstimate(t_ns=t_ns, source=DEVICE,
                                   q_body_to_ned=tuple(IDENTITY_QUATERNION),
                                   linear_accel_ned_m_s2=(0.0, 0.0, -float(c[ACCEL_UP][i])))
        if math.isnan(c[ALTITUDE][i]):
            continue
        try:
            p = pressure_pa_at_altitude(float(c[ALTITUDE][i]), sea_level_pa)
        except ValueError as exc:
            raise InputError(f"{table.path}: line {table.lines[i]}, column '{ALTITUDE}': "
                             f"{exc}") from None
        yield PressureSample(t_ns=t_ns, device=DEVICE, pressure_pa=p)


def _stack(table: SampleTable, names: tuple[str, ...]) -> np.ndarray:
    return np.stack([table.columns[n] for n in names], axis=1)


def smoothed_estimates(estimator: Estimator, table: SampleTable) -> list[Estimate]:
    """An estimator's offline mode (``offline: true``): its ``smooth`` method over the whole
    table at once (the recording known in advance), one attitude per row. The magnetometer
    is used only when every row has a sample (an offline smoother takes one rate)."""
    smooth = getattr(estimator, "smooth", None)
    if smooth is None:
        raise InputError(f"estimator {estimator.name!r} has no offline mode; drop offline")
    require(table, (TIME, *GYRO, *ACCEL), "an attitude estimator")
    c = table.columns
    mag = _stack(table, MAG) if table.has(*MAG) else None
    if mag is not None and np.isnan(mag).any():
        mag = None
    q = smooth(_stack(table, GYRO), _stack(table, ACCEL), mag)
    return [AttitudeEstimate(t_ns=round(float(t) * 1e9), source=estimator.instance,
                             q_body_to_ned=(float(w), float(x), float(y), float(z)))
            for t, (w, x, y, z) in zip(c[TIME], q, strict=True)]


def run_offline(
    estimator: Estimator, table: SampleTable, *, ahrs: Estimator | None = None,
) -> list[Estimate]:
    """Run ``estimator`` over ``table``; ``ahrs`` supplies attitude to a vario filter fed
    full IMU columns plus ``pressure_pa`` (imuhal then does the gravity compensation)."""
    return _run_table(estimator, table, ahrs)  # type: ignore[return-value]  # the table path returns attitude or vertical estimates, a list of Estimate subclasses


def iter_offline(
    estimator: Estimator, tables: Iterable[SampleTable], *, ahrs: Estimator | None = None,
    columnar: bool = False,
) -> Iterator[list[Estimate] | AttitudeRows]:
    """:func:`run_offline` over a stream of tables (chunks of one log, in time order): the
    estimators keep their state from one chunk to the next; one list of estimates per chunk.
    ``columnar``: an attitude estimator that takes whole chunks (:class:`RowsEstimator`)
    gets them, and the chunk's estimates come as :class:`AttitudeRows` (same values)."""
    for table in tables:
        yield _run_table(estimator, table, ahrs, columnar)


def run_offline_columns(estimator: Estimator, table: SampleTable) -> list[Estimate] | AttitudeRows:
    """:func:`run_offline`, as :class:`AttitudeRows` when the estimator takes whole chunks."""
    return _run_table(estimator, table, None, True)


def _run_table(estimator: Estimator, table: SampleTable, ahrs: Estimator | None,
               columnar: bool = False) -> list[Estimate] | AttitudeRows:
    if _wants_imu(estimator):
        if getattr(estimator.settings, "offline", False):
            return smoothed_estimates(estimator, table)
        if columnar and isinstance(estimator, RowsEstimator):
            return estimator.attitude_rows(imu_blocks(table))
        return fuse_table([estimator], table)
    _require_pressure_consumer(estimator)
    if table.has(ALTITUDE):
        sea_level = float(getattr(estimator.settings, "sea_level_pa", SEA_LEVEL_PRESSURE_PA))
        return feed(estimator, vario_events(table, sea_level))
    require(table, (TIME, *GYRO, *ACCEL, PRESSURE),
            "a vario filter (or give t_s, altitude_m, accel_up_m_s2)")
    if ahrs is None:
        raise InputError("full IMU input needs an attitude estimator for gravity compensation")
    return [e for e in fuse_table([ahrs, estimator], table) if e.source == estimator.instance]


def run_offline_samples(
    estimator: Estimator, samples: Iterable[Sample], *, ahrs: Estimator | None = None,
) -> list[Estimate]:
    """Run ``estimator`` over samples as the pipeline produced them (a run log, in order),
    each instant's in fusion order as live; a vario filter gets its attitude from ``ahrs``
    run over the same samples."""
    samples = instants_in_fusion_order(samples)
    if _wants_imu(estimator):
        return feed(estimator, samples)
    _require_pressure_consumer(estimator)
    if ahrs is None:
        raise InputError("a vario filter over a run log needs an attitude estimator for "
                         "gravity compensation (--ahrs NAME)")
    return feed(estimator, samples, ahrs=ahrs)


def feed(estimator: Estimator, items: Iterable[Sample | Estimate], *,
         ahrs: Estimator | None = None) -> list[Estimate]:
    """Each item (and what ``ahrs`` makes of it) to ``estimator`` when it consumes it."""
    if ahrs is not None:
        source = estimator.instance
        made: list[Estimate] = []
        process = EstimatorChain((ahrs, estimator)).process
        for item in items:
            process(item, made)
        return [e for e in made if e.source == source]
    consumes = tuple(estimator.consumes)
    outputs: list[Estimate] = []
    process, extend = estimator.process, outputs.extend  # type: ignore[assignment]  # a second loop variable of another estimator kind: the same name, a narrower call
    # the common case, kept lean: it runs once per input row
    for item in items:
        if isinstance(item, consumes):
            extend(process(item))
    # as live: a value that is not finite or not normalisable reaches no output
    checked_estimates(outputs, type(estimator).name)
    return outputs


def _wants_imu(estimator: Estimator) -> bool:
    consumes = tuple(estimator.consumes)
    return any(issubclass(t, (GyroSample, AccelSample)) for t in consumes) and not any(
        issubclass(t, PressureSample) for t in consumes)


def _require_pressure_consumer(estimator: Estimator) -> None:
    consumes = tuple(estimator.consumes)
    if not any(issubclass(t, PressureSample) for t in consumes):
        raise InputError(f"estimator {estimator.name!r} consumes "
                         f"{', '.join(t.__name__ for t in consumes)}: imuhal estimate cannot "
                         "build those from a CSV")
