"""A bus a chip provides (``DEVICE/CHILD``) may be of any kind: the parent's driver declares
each child bus and its kind, and the profile checks the chips behind it against that."""

from __future__ import annotations

import textwrap
from typing import ClassVar

import pytest
from tests.support import testchip

from imuhal.bus.base import BusKind
from imuhal.core.errors import ProfileError
from imuhal.plugins import builtin_buses, hookimpl
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import parse_profile


class Hub(testchip.TC3Driver):
    """A chip with an SPI master of its own (not an I2C one)."""

    name: ClassVar[str] = "tc3-hub"
    child_bus_kinds = {"spi": BusKind.SPI}  # noqa: RUF012 - a class constant


class I2cOnly(testchip.TC3Driver):
    name: ClassVar[str] = "tc3-i2c"
    bus_kinds = frozenset({BusKind.I2C})


class SpiOnly(testchip.TC3Driver):
    name: ClassVar[str] = "tc3-spi"
    bus_kinds = frozenset({BusKind.SPI})


class _Plugin:
    @hookimpl
    def imuhal_register_drivers(self, register):  # type: ignore[no-untyped-def]
        for cls in (Hub, I2cOnly, SpiOnly):
            register(cls)


@pytest.fixture(scope="module")
def hub_registry() -> Registry:
    return load_registry(entry_point_plugins=False,
                         extra=[("buses", builtin_buses), ("hub", _Plugin())])


def _profile(child_driver: str, child_bus: str = "hub/spi") -> str:
    return textwrap.dedent(f"""\
        schema_version: 1
        name: hub-board
        buses:
          i2c1: {{kind: i2c, device: /dev/i2c-1}}
        devices:
          hub: {{driver: tc3-hub, bus: i2c1, address: 0x19}}
          leaf: {{driver: {child_driver}, bus: {child_bus}, address: 0}}
        """)


def test_a_chip_on_a_child_spi_bus_loads(hub_registry: Registry) -> None:
    profile = parse_profile(_profile("tc3-spi"), "hub.yaml", hub_registry)
    assert profile.devices["leaf"].bus == "hub/spi"


def test_an_i2c_only_chip_behind_a_child_spi_bus_is_refused(hub_registry: Registry) -> None:
    with pytest.raises(ProfileError) as info:
        parse_profile(_profile("tc3-i2c"), "hub.yaml", hub_registry)
    assert any("devices.leaf.bus: tc3-i2c cannot sit on a spi bus" in p
               for p in info.value.problems)


def test_a_child_bus_the_parent_does_not_provide_is_named(hub_registry: Registry) -> None:
    with pytest.raises(ProfileError) as info:
        parse_profile(_profile("tc3-spi", "hub/aux"), "hub.yaml", hub_registry)
    assert any("device 'hub' (tc3-hub) provides no bus 'aux'; it provides: spi" in p
               for p in info.value.problems)
