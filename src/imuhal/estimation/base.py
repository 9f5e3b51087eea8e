"""What every estimator provides.

An estimator consumes samples (body frame, project units) and other estimators' outputs, and
produces Estimates. Its settings are a pydantic model kept apart from its state; its state
can be saved and restored. It knows nothing about buses or chips.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict

from imuhal.core.blocks import Block
from imuhal.core.samples import Sample
from imuhal.core.streams import StreamSpec
from imuhal.estimation.ordering import blocks_in_fusion_order
from imuhal.estimation.outputs import AttitudeBlock, Estimate


class EstimatorSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Estimator(ABC):
    """Base of every estimator plugin.

    ``consumes`` lists the sample and estimate types the pipeline should hand to ``process``.
    """

    name: ClassVar[str]
    description: ClassVar[str] = ""
    Settings: ClassVar[type[EstimatorSettings]]
    consumes: ClassVar[tuple[type, ...]]

    def __init__(self, settings: EstimatorSettings | dict[str, Any] | None = None,
                 *, instance: str | None = None) -> None:
        if settings is None:
            settings = self.Settings()
        elif not isinstance(settings, self.Settings):
            settings = self.Settings.model_validate(settings)
        self.settings = settings
        self.given_settings: frozenset[str] = frozenset(settings.model_fields_set)
        """The settings the user gave (the others may follow the streams, ``bind``)."""
        self.instance = instance or self.name
        self.reset()

    @abstractmethod
    def reset(self) -> None:
        """Return to the initial state."""

    @abstractmethod
    def process(self, item: Sample | Estimate) -> list[Estimate]:
        """Consume one body-frame sample or upstream estimate; return new estimates."""

    def update_block(self, block: Block) -> list[Estimate]:
        """Consume every frame of ``block`` (imuhal.core.blocks: n valid, body-frame frames
        of one stream, oldest first) with nothing else between them; return the estimates,
        in the order made. The result is what ``process()`` makes of the frames one by one
        (the default does exactly that, so an estimator that only implements ``process``
        takes blocks too); an estimator with a faster way over arrays overrides it and
        must give the same estimates. The pipeline's router (imuhal.pipeline.router) hands
        a block over whole only when nothing else of its instants is routed here."""
        return _frame_by_frame(self, block.samples())

    def update_blocks(self, blocks: Sequence[Block]) -> list[Estimate]:
        """Consume the frames of ``blocks`` (one fusion step: valid, body-frame blocks of
        different quantities, e.g. a FIFO read's accelerometer and gyro frames) in fusion
        order (imuhal.estimation.ordering: by time, then accelerometer, magnetometer,
        pressure, temperature, gyro), with nothing else between them; return the
        estimates, in the order made. The default hands the frames to ``process()`` one
        by one in that order; an estimator with a faster way over arrays (the AHRS family)
        overrides it and must give the same estimates. The router hands over the blocks of
        a fusion step at once only when nothing else of the step reaches this estimator."""
        if len(blocks) == 1:
            return _frame_by_frame(self, blocks[0].samples())
        return _frame_by_frame(self, blocks_in_fusion_order(blocks))

    def estimate_blocks(self, blocks: Sequence[Block]) -> list[Estimate | AttitudeBlock]:
        """``update_blocks`` for a caller that takes estimates as blocks too (the live
        pipeline's router): the same estimates, where the estimator can, as
        :class:`~imuhal.estimation.outputs.AttitudeBlock` s whose rows are those estimates
        (no object built per frame until one is asked for). The default returns
        ``update_blocks``'s."""
        return list(self.update_blocks(blocks))

    def update_estimate_block(self, block: AttitudeBlock) -> list[Estimate]:
        """Consume the attitude estimates of ``block`` (one upstream estimator's, in the
        order made) with nothing else between them; the result is what ``process()``
        makes of its rows one by one (the default does exactly that); an estimator with a
        faster way over the columns overrides it and must give the same estimates."""
        out: list[Estimate] = []
        process = self.process
        for estimate in block.rows():
            made = process(estimate)
            if made:
                out.extend(made)
        return out

    def moving_at_start(self, t_ns: int) -> None:
        """The pipeline's gyro start-up measurement (imuhal.pipeline.startup) gave up at
        ``t_ns`` (ns), just before this estimator's first samples, because the board moved at
        switch-on (a start in flight, a board in a hand). An estimator that assumes a still
        start may check its own (an AHRS's ``start_check_s``). The default: nothing to
        check."""
        del t_ns  # an estimator that makes no assumption about its start takes nothing

    @abstractmethod
    def get_state(self) -> dict[str, Any]:
        """A JSON-serialisable snapshot of the state (not the settings)."""

    @abstractmethod
    def set_state(self, state: dict[str, Any]) -> None:
        """Restore a snapshot taken by get_state."""

    def bind(self, streams: Sequence[StreamSpec]) -> None:
        """Take what this estimator needs from the specs of the streams it is fed
        (imuhal.core.streams; plain data, never a driver): limits, nominal periods, rates.
        Called by the pipeline before the first sample and again when an input device joins
        or comes back reconfigured; ``imuhal estimate`` calls it with specs measured from
        the log. A setting the user gave (``given_settings``) that contradicts a stream
        raises imuhal.estimation.streams.StreamContradiction. An estimator whose settings
        change here starts again from its initial state. The default: nothing to bind."""
        del streams  # an estimator without rate or limit settings takes nothing

    def diagnostics(self) -> dict[str, Any]:
        return {}


def _frame_by_frame(estimator: Estimator, samples: Sequence[Sample]) -> list[Estimate]:
    """``samples`` through ``estimator.process`` one by one; every estimate, in order."""
    out: list[Estimate] = []
    process = estimator.process
    for sample in samples:
        made = process(sample)
        if made:
            out.extend(made)
    return out
