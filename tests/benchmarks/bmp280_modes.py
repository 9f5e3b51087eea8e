"""What gy91's BMP280 costs and gives in normal and in forced mode (plain script; not
collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.bmp280_modes [--duration 60]
      [--scenarios thermal,static]

gy91's profile (x8 pressure, x1 temperature oversampling, IIR 4, ``odr_hz`` 25) flown with
its BMP280 in each mode: ``normal`` (the shortest standby reaching 25 Hz, 0.5 ms: the chip
cycles every 20 ms, 50 Hz), ``forced`` at the profile's 25 Hz and ``forced`` at 40 Hz (the
datasheet's maximum conversion time at these oversamplings, 22.5 ms, allows 44.4 Hz). Seed
1, the chips' datasheet error models, nominal clocks. Per run: valid pressures a second,
bus transfers a second to the barometer (a forced conversion costs the trigger's write and
the burst read; a normal one the read), the spread of the pressure's error against the
truth at its stamp about its mean (its noise and lag; the mean is the error model's
offset), and the vario's (vario-kf3 behind the AHRS) climb-rate RMS error against the
truth after SETTLE_S.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from imuhal.bus.spy import Transfer
from imuhal.core.samples import PressureSample
from imuhal.emulation import EmulatedBoard, open_emulated
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile

PROFILE = Path(__file__).resolve().parents[2] / "profiles" / "gy91.yaml"
MODES: tuple[tuple[str, float], ...] = (("normal", 25.0), ("forced", 25.0), ("forced", 40.0))
SCENARIOS = ("thermal", "static")
DURATION_S = 60.0
SETTLE_S = 10.0


def _sd(values: list[float]) -> float:
    """The spread about the mean (the error model's offset left out: the noise)."""
    mean = sum(values) / len(values) if values else math.nan
    return _rms([v - mean for v in values])


def _rms(values: list[float]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values)) if values else math.nan


def fly(scenario: str, mode: str, odr_hz: float, duration_s: float) -> dict[str, float]:
    registry = load_registry()
    profile = load_profile(PROFILE, registry)
    settings = profile.devices["baro"].settings
    settings["mode"], settings["odr_hz"] = mode, odr_hz
    address = profile.devices["baro"].address
    transfers = 0
    pressure_off: list[float] = []
    climb_off: list[float] = []

    def count(t: Transfer) -> None:
        nonlocal transfers
        transfers += t.target == address

    with open_emulated(profile, registry, seed=1, scenario=scenario,
                       trace=count) as pipeline:
        board = EmulatedBoard.of(pipeline)
        for event in pipeline.events(duration_s):
            if isinstance(event, PressureSample) and event.device == "baro" and event.valid:
                pressure_off.append(event.pressure_pa - board.truth_at(event.t_ns).pressure_pa)
            elif isinstance(event, VerticalEstimate) and event.t_ns >= SETTLE_S * 1e9 \
                    and math.isfinite(event.climb_m_s):
                climb_off.append(event.climb_m_s - board.truth_at(event.t_ns).climb_m_s)
    return {"pressures_per_s": len(pressure_off) / duration_s,
            "transfers_per_s": transfers / duration_s,
            "pressure_sd_pa": _sd(pressure_off),
            "climb_rms_m_s": _rms(climb_off)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=DURATION_S, help="simulated s per run")
    p.add_argument("--scenarios", default=",".join(SCENARIOS), help="comma-separated")
    args = p.parse_args(argv)
    print(f"gy91, {args.duration:g} s of each scenario, seed 1, datasheet error models, "
          f"nominal clocks; climb after {SETTLE_S:g} s\n")
    print("| scenario | BMP280 mode | valid pressures / s | bus transfers / s | pressure off the "
          "truth: SD about its mean (Pa) | vario climb RMS off the truth (m/s) |")
    print("| --- | --- | ---: | ---: | ---: | ---: |")
    for scenario in args.scenarios.split(","):
        for mode, odr_hz in MODES:
            r = fly(scenario, mode, odr_hz, args.duration)
            what = f"{mode} ({odr_hz:g} Hz asked)" if mode == "normal" else \
                f"{mode} at {odr_hz:g} Hz"
            print(f"| {scenario} | {what} | {r['pressures_per_s']:.1f} "
                  f"| {r['transfers_per_s']:.1f} | {r['pressure_sd_pa']:.2f} "
                  f"| {r['climb_rms_m_s']:.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
