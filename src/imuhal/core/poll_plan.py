"""Which poll plan the drivers follow: the bus traffic a run makes, by version.

A driver may change when it talks to its chip (two transfers merged into one poll, say) only
under a new plan version, keeping the old plan beside it: a recording holds the plan it was
made with (its header's ``poll_plan``, docs/recording.md), and a replay, which checks every
transfer against the recording, runs the drivers on that plan.
"""

from __future__ import annotations

POLL_PLAN = 5
"""The plan a run follows and a recording made now holds. 2: the HMC5883L behind a master's
FIFO reads looks for its copies no sooner than the master's next read
(imuhal_chips.hmc5883l.driver, ``_next_look``). 3: the MAX21100 read from its FIFO reads
its auto-read slave's copy a guard after each of its instants, between the FIFO reads
(imuhal_chips.max2110x.driver, ``_next_read_ns``), not beside each FIFO read. 4
(``CHIP_CLOCK_PLAN``): the polls follow a chip clock off its nominal period, and a chip
reset; and a BMP280 whose forced trigger write failed reads its burst to tell whether the
conversion started, instead of the full recovery (imuhal_chips.bmp280.driver,
``TRIGGER_CHECK_PLAN``). 5 (``FIFO_RESET_PLAN``): an MPU-9250 read from its FIFO keeps
the period it learnt across a chip reset, and a chip clock restarted before it first
settled keeps the period's bounds learnt so far; the HMC5883L behind a master, on a grid
ahead of a slow chip's instants, makes its periodic read-back at a poll that takes a fresh
change (``READ_BACK_PLAN``); the pipeline counts a retry the host held late on its frame's
phase (``LATE_RETRY_PLAN``)."""

CHIP_CLOCK_PLAN = 4
"""The plan from which a tracking poll grid learns no period more than
``PollGrid.PERIOD_ERROR_AT_MOST`` off its nominal one (``bounded``); the MAX2110x's polled
reads catch up with a chip faster than their early step (``PollGrid(catch_up=True)``); the
HMC5883L behind a master steers its poll grid with the chip's clock (``_steer``); and a
MAX2110x read from its FIFO keeps the period it learnt across a chip reset, reading every
half period while it learns the phase again (``FifoFrames.cleared(same_oscillator=True)``).
On a nominal clock without resets none of them changes a transfer; each moves the polls,
and so the transfers, of a chip whose clock is off (real hardware) or that reset."""

FIFO_RESET_PLAN = 5
"""The plan from which an MPU-9250 read from its FIFO keeps the period its chip clock
learnt across a chip reset at the same settings (imuhal_chips.mpu9250.driver, as the
MAX2110x does from CHIP_CLOCK_PLAN), and a chip clock restarted at the same oscillator
before its estimate first settled keeps the period's bounds its reads proved so far
(``ChipClock.keep_unsettled``; before: it learnt the period afresh). On a nominal clock
without resets neither changes a transfer; both move the reads after a reset of a chip
read from its FIFO."""

READ_BACK_PLAN = 5
"""The plan from which the HMC5883L behind a master (``read: auto``), its grid steered
ahead of a slow chip's instants, makes its periodic read-back of Mode (which locks the
chip's outputs until the master's next copy) only at a poll that takes a fresh change
(imuhal_chips.hmc5883l.driver, ``_read_back_now``; before: at the first poll due). On a
nominal clock it changes no transfer; on a chip clock slow by more than about 1 % it moves
read-backs."""

LATE_RETRY_PLAN = 5
"""The plan from which the pipeline counts a retry after a bus error that the host held
more than a guard late on the phase of the frame before (imuhal.pipeline.pipeline,
``Pipeline._count_late_retry``). That count point is where a later put-off poll aims
(``Pipeline._aim``), so it moves the polls of a run with bus errors."""

FIRST_POLL_PLAN = 1
"""The plan of a recording whose header names none (made before plans had versions)."""
