"""What a chip emulator is: a bus face (register file, state machines) and a physics face.

A driver talks to an emulator only through a bus, exactly as to silicon. The simulation talks
to it only through ``set_physics``, handing it true values in the chip's own sensor frame and
in SI units; the emulator encodes them with the chip's configured range and resolution when
its measurement completes.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

from pydantic import ValidationError

from imuhal.bus.base import BusKind
from imuhal.core.clock import Clock, SimulatedClock
from imuhal.core.samples import Channel
from imuhal.sim.errors import SensorErrorSpec
from imuhal.sim.inputs import PhysicalInputs

if TYPE_CHECKING:
    from imuhal.sim.emulated_bus import EmulatedBus


class ChipEmulator(ABC):
    """Base of every chip emulator.

    ``clock`` is the simulated clock the emulator measures conversion and data-ready timing
    against. ``absent`` makes the chip NACK every transfer (fault injection).
    """

    #: The driver name this emulator stands in for (the registry pairs them by it).
    chip: str = ""
    #: The chip's datasheet noise and bias figures that the simulator applies to the truth
    #: before this emulator encodes it; None: an ideal chip. A subclass may give a
    #: :class:`~imuhal.sim.errors.SensorErrorSpec` or a mapping of its fields; the mapping is
    #: validated when the class is defined, so a typo in a plugin fails at import, naming it.
    error_spec: ClassVar[SensorErrorSpec | None] = None
    #: Opt-in to imuhal's generic conformance sweep, which checks the pair against an
    #: independent table in imuhal's own test data; a third-party emulator leaves it False.
    conformance_sweep: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        spec = cls.__dict__.get("error_spec")
        if spec is not None and not isinstance(spec, SensorErrorSpec):
            if not isinstance(spec, Mapping):
                raise TypeError(f"{cls.__name__}.error_spec must be a SensorErrorSpec or a "
                                f"mapping of its fields, not {type(spec).__name__}")
            try:
                cls.error_spec = SensorErrorSpec.model_validate(spec)
            except ValidationError as exc:
                raise TypeError(f"{cls.__name__}.error_spec is not a valid SensorErrorSpec: "
                                f"{exc}") from None

    def __init__(self, clock: Clock | None = None) -> None:
        self.clock: Clock = clock if clock is not None else SimulatedClock()
        self.absent = False
        self.physics = PhysicalInputs()

    @abstractmethod
    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        """Answer one bus transaction (write then read) as the chip would."""

    def set_physics(self, inputs: PhysicalInputs) -> None:
        """Hand the emulator the true values it should measure from now on."""
        self.physics = inputs

    def now_ns(self) -> int:
        return self.clock.now_ns()

    # -- conventions every emulator follows where its chip has the feature ----------------

    def resolution(self, channel: Channel) -> float:
        """SI units per count of ``channel`` in the current configuration."""
        raise NotImplementedError(f"{type(self).__name__} does not report its resolution")

    def full_scale(self, channel: Channel) -> float:
        """The largest magnitude (SI) ``channel`` can report in the current configuration."""
        raise NotImplementedError(f"{type(self).__name__} does not report its full scale")

    def silent_reset(self) -> None:
        """Fault injection: the chip resets without telling anyone (configuration lost)."""
        raise NotImplementedError(f"{type(self).__name__} does not model a silent reset")

    def connect_host(self, host_bus: EmulatedBus) -> None:  # noqa: B027 - optional hook
        """Called once the whole board is attached, with the bus this chip sits on. A chip
        with an I2C bypass switch joins its child bus to ``host_bus`` here."""

    def child_buses(self) -> dict[str, EmulatedBus]:
        """Downstream buses this chip masters (e.g. the MAX21100's I2C master), by the same
        local names its driver's ``child_buses`` uses. Emulators of chips behind it are
        attached to these, and this emulator performs real transfers on them."""
        return {}
