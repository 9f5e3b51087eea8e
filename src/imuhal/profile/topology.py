"""Board topology: devices ordered so that a chip providing a bus comes before the chips
behind it, and each device's rotation into the body frame."""

from __future__ import annotations

from imuhal.core.errors import ProfileError
from imuhal.core.frames import FloatArray, parse_mount
from imuhal.profile.model import BoardProfile


def device_order(profile: BoardProfile) -> list[str]:
    """Enabled device names, parents (bus providers) first, otherwise in profile order."""
    enabled = {n: d for n, d in profile.devices.items() if d.enabled}
    order: list[str] = []
    visiting: set[str] = set()

    def visit(name: str, chain: tuple[str, ...]) -> None:
        if name in order:
            return
        if name in visiting:
            raise ProfileError("profile", [f"devices form a bus cycle: {' -> '.join(chain)}"])
        visiting.add(name)
        bus = enabled[name].bus
        if "/" in bus:
            parent = bus.split("/", 1)[0]
            if parent not in enabled:
                raise ProfileError("profile", [
                    f"devices.{name}.bus: {bus!r} needs device {parent!r}, which is disabled"])
            visit(parent, (*chain, parent))
        visiting.discard(name)
        order.append(name)

    for name in enabled:
        visit(name, (name,))
    return order


def split_bus_ref(bus: str) -> tuple[str, str | None]:
    """``"imu/aux"`` -> ("imu", "aux"); ``"spi0"`` -> ("spi0", None)."""
    if "/" in bus:
        parent, child = bus.split("/", 1)
        return parent, child
    return bus, None


def chip_to_body_rotations(profile: BoardProfile) -> dict[str, FloatArray]:
    """Each enabled device's rotation chip -> body: ``board_to_body @ mount``."""
    board_to_body = parse_mount(profile.board_to_body)
    return {n: board_to_body @ parse_mount(d.mount) for n, d in profile.devices.items()
            if d.enabled}
