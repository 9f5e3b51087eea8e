"""Which poll plan the drivers follow: the bus traffic a run makes, by version.

A driver may change when it talks to its chip (two transfers merged into one poll, say) only
under a new plan version, keeping the old plan beside it: a recording holds the plan it was
made with (its header's ``poll_plan``, docs/recording.md), and a replay, which checks every
transfer against the recording, runs the drivers on that plan.
"""

from __future__ import annotations

POLL_PLAN = 3
"""The plan a run follows and a recording made now holds. 2: the HMC5883L behind a master's
FIFO reads looks for its copies no sooner than the master's next read
(imuhal_chips.hmc5883l.driver, ``_next_look``). 3: the MAX21100 read from its FIFO reads
its auto-read slave's copy a guard after each of its instants, between the FIFO reads
(imuhal_chips.max2110x.driver, ``_next_read_ns``), not beside each FIFO read."""

FIRST_POLL_PLAN = 1
"""The plan of a recording whose header names none (made before plans had versions)."""
