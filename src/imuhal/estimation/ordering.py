"""The order in which samples of one instant reach the estimators, live and offline alike.

A driver may emit the samples of one burst in any order (the MAX2110x emits the gyro before
the accelerometer, the MPU-9250 the other way round), and two devices may produce samples
with the same timestamp. An AHRS steps on each gyro sample with the latest accelerometer and
magnetometer samples, so without a rule the result would depend on emission order. The rule:
samples with the same ``t_ns`` are handed over accelerometer, magnetometer, pressure,
temperature, then gyro (the gyro step uses the other measurements of its own instant); ties
are broken by device rank (profile order live; one device offline).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

from imuhal.core.blocks import Block
from imuhal.core.gaps import GAP
from imuhal.core.samples import Quantity, Sample

FUSION_RANK: dict[Quantity, int] = {
    GAP: -1,
    Quantity.ACCEL: 0,
    Quantity.MAG: 1,
    Quantity.PRESSURE: 2,
    Quantity.TEMPERATURE: 3,
    Quantity.GYRO: 4,
}
"""Position of each quantity among the samples of one instant (a stream's gap first: it
says what was lost before the frames of its instant; gyro last)."""


def fusion_order(samples: Iterable[Sample],
                 device_rank: Mapping[str, int] | None = None) -> list[Sample]:
    """``samples`` sorted by time, then FUSION_RANK, then device rank: the order estimators
    receive them in. Independent of the order they were given in."""
    ranks = device_rank or {}
    if type(samples) is list and len(samples) == 2:
        # the common case live (a gyro and an accelerometer sample of one burst): what the
        # stable sort gives, without setting one up (the keys written out)
        a, b = samples
        if (a.t_ns, FUSION_RANK.get(a.channel, 2), ranks.get(a.device, 0)) > \
                (b.t_ns, FUSION_RANK.get(b.channel, 2), ranks.get(b.device, 0)):
            return [b, a]
        return [a, b]

    def key(s: Sample) -> tuple[int, int, int]:
        return s.t_ns, FUSION_RANK.get(s.channel, 2), ranks.get(s.device, 0)

    return sorted(samples, key=key)


def blocks_in_fusion_order(blocks: Sequence[Block]) -> list[Sample]:
    """The frames of ``blocks`` in :func:`fusion_order` without device ranks (by time, then
    FUSION_RANK; frames equal in both keep their order in ``blocks``, block by block): one
    sort of (time, rank, block, frame) tuples, which never compares two samples, rather
    than a key function called per frame."""
    keyed = [(s.t_ns, rank, i, j, s)
             for i, b in enumerate(blocks)
             for rank in (FUSION_RANK.get(b.quantity, 2),)
             for j, s in enumerate(b.samples())]
    keyed.sort()
    return [k[4] for k in keyed]
