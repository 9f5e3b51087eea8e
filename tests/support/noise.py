"""Each chip's datasheet noise without its biases, scale and iron errors: for board-level
tests of something other than accuracy that still need a chip that behaves like a real one
(an ideal emulator at rest repeats one raw frame for ever, which drivers flag FROZEN)."""

from __future__ import annotations

from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile
from imuhal.sim.errors import SensorErrorSpec, error_spec_of

NOISE_FIELDS = ("noise_density", "noise_std", "bandwidth_hz")


def noise_only_specs(profile: BoardProfile, registry: Registry) -> dict[str, SensorErrorSpec]:
    """Device -> its emulator's error spec reduced to white noise (for ``open_emulated``'s
    ``error_specs``)."""
    out: dict[str, SensorErrorSpec] = {}
    for name, device in profile.devices.items():
        reg = registry.emulators.entries.get(device.driver)
        spec = error_spec_of(reg.obj) if reg is not None else None
        if spec is None:
            continue
        channels = {
            channel: {k: v for k, v in value.items() if k in NOISE_FIELDS}
            for channel, value in spec.model_dump().items() if value is not None
        }
        out[name] = SensorErrorSpec.model_validate(channels)
    return out
