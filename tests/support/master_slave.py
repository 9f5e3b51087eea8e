"""A magnetometer behind an IMU's I2C master, polled as the pipeline polls them.

Shared by the slave auto-read tests of the MAX21100 + HMC5883L and the MPU-9250 + AK8963:
each builds its board (clock, emulators, drivers, dithers) and inherits the poll loop."""

from __future__ import annotations

from tests.support.dither import Dither

from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import ImuhalError
from imuhal.core.samples import MagSample, Sample
from imuhal.drivers.base import Driver


class MasterSlaveBoard:
    """Set ``clock``, ``imu``, ``mag`` and ``dithers`` before calling :meth:`run`."""

    clock: SimulatedClock
    imu: Driver
    mag: Driver
    dithers: tuple[Dither, ...]

    def __init__(self) -> None:
        self.schedule: dict[Driver, int] = {}
        self.errors = 0
        """Polls that raised (the pipeline counts them and recovers the device)."""
        self.mag_polls = 0
        self.empty_mag_polls = 0
        """The magnetometer's polls, and those that handed out nothing."""

    def run(self, seconds: float) -> list[Sample]:
        """Poll both drivers at the times they ask for (the IMU first at a tie, as the
        pipeline does); the mag samples."""
        drivers = (self.imu, self.mag)
        if not self.schedule:
            now = self.clock.now_ns()
            self.schedule = {d: d.start(now) for d in drivers}
        end = self.clock.now_ns() + round(seconds * 1e9)
        out: list[Sample] = []
        while True:
            driver = min(drivers, key=lambda d: self.schedule[d])
            if self.schedule[driver] > end:
                return out
            self.clock.sleep_until(self.schedule[driver])
            for dither in self.dithers:
                dither()
            now = self.clock.now_ns()
            try:
                result = driver.poll(now)
            except ImuhalError:  # as the pipeline does: recover, retry 10 ms later
                self.errors += 1
                try:
                    self.schedule[driver] = driver.recover(now)
                except ImuhalError:
                    self.schedule[driver] = now + 10_000_000
                continue
            if driver is self.mag:
                out += result.samples
                self.mag_polls += 1
                self.empty_mag_polls += not result.samples
            self.schedule[driver] = max(result.next_poll_ns, self.clock.now_ns() + 1)


def valid_mag(samples: list[Sample]) -> list[MagSample]:
    """The valid magnetometer samples among ``samples``."""
    return [s for s in samples if isinstance(s, MagSample) and s.valid]
