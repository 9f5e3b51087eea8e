"""A live run's estimators, built afresh and chained offline over its recorded samples."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from imuhal.core.samples import Sample
from imuhal.core.streams import StreamSpec
from imuhal.estimation.outputs import Estimate
from imuhal.offline.chain import run_chain
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile


def offline_estimates(registry: Registry, profile: BoardProfile,
                      streams: Mapping[str, Sequence[StreamSpec]],
                      samples: list[Sample]) -> list[Estimate]:
    """The profile's estimators, fresh, bound to the input devices' ``streams`` (what the
    pipeline bound into each, ``Pipeline.streams``) and chained by ``run_chain`` over
    ``samples`` with the profile's ``inputs``."""
    fresh = [registry.estimators.get(c.estimator)(c.settings, instance=name)
             for name, c in profile.estimators.items()]
    for est, c in zip(fresh, profile.estimators.values(), strict=True):
        est.bind([spec for device in (c.inputs or streams) if device in streams
                  for spec in streams[device]])
    inputs = {name: c.inputs for name, c in profile.estimators.items() if c.inputs is not None}
    return run_chain(fresh, samples, inputs=inputs)
