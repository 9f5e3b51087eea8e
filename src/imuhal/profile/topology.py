"""Ordering devices so that a chip providing a bus comes before the chips behind it."""

from __future__ import annotations

from imuhal.core.errors import ProfileError
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
