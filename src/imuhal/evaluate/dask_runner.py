"""The evaluation on Dask: one task per trial and setting (``pip install imuhal[dask]``).

Each task gets a recording's *source* (its path) and one estimator spec, loads the recording
on its worker, builds the plugin registry there (the workers need imuhal and the plugins
installed, and the recording paths readable) and returns a TrialResult. Results come back in
the serial run's order, and each task computes exactly what ``run_job`` computes serially, so
the two runs give identical numbers.

``scheduler=None`` starts a local cluster (``workers`` processes, one thread each: the
estimators are pure Python and hold the GIL); ``scheduler="tcp://host:8786"`` uses a running
cluster; ``scheduler="threads"`` or ``"sync"`` runs Dask's in-process schedulers (tests).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from typing import Any

from imuhal.core.errors import ImuhalError
from imuhal.evaluate.recording import RecordingSource
from imuhal.evaluate.runner import EstimatorSpec, Progress, TrialResult, jobs, run_job
from imuhal.plugins.manager import Registry


class DaskUnavailable(ImuhalError):
    pass


@lru_cache(maxsize=1)
def _worker_registry() -> Registry:
    from imuhal.plugins import load_registry

    return load_registry()


@lru_cache(maxsize=4)
def _load(source: RecordingSource) -> Any:
    return source.load()


def evaluation_task(source: RecordingSource, spec: EstimatorSpec) -> TrialResult:
    """One trial x setting on a worker."""
    return run_job(_load(source), spec, _worker_registry())


def evaluate_dask(sources: Sequence[RecordingSource], specs: Sequence[EstimatorSpec], *,
                  scheduler: str | None = None, workers: int | None = None,
                  progress: Progress | None = None) -> list[TrialResult]:
    """Every source with every spec as separate Dask tasks; results in the serial order."""
    try:
        import dask
        from dask import delayed
    except ImportError:
        raise DaskUnavailable("--dask needs dask: pip install 'imuhal[dask]'") from None
    job_list = list(jobs(sources, specs))
    if scheduler in ("threads", "sync", "synchronous", "processes"):
        tasks = [delayed(evaluation_task, pure=True)(src, spec) for src, spec in job_list]
        results = list(dask.compute(*tasks, scheduler=scheduler))
        if progress is not None:
            for i, r in enumerate(results, 1):
                progress(i, len(results), r)
        return results
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise DaskUnavailable("a Dask cluster needs distributed: pip install "
                              "'imuhal[dask]'") from None
    cluster = None
    if scheduler is None:
        cluster = LocalCluster(n_workers=workers or 1, threads_per_worker=1,
                               processes=True, dashboard_address=":0")
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout="10s")
        except OSError as exc:
            raise DaskUnavailable(f"--scheduler {scheduler}: cannot connect ({exc}); start "
                                  "one with `dask scheduler` or drop --scheduler") from None
    try:
        futures = [client.submit(evaluation_task, src, spec, pure=False)
                   for src, spec in job_list]
        index = {f.key: i for i, f in enumerate(futures)}
        slots: list[TrialResult | None] = [None] * len(futures)  # in the serial order
        for done, fut in enumerate(as_completed(futures), 1):
            slots[index[fut.key]] = fut.result()
            if progress is not None:
                progress(done, len(futures), fut.result())
        return [r for r in slots if r is not None]
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
