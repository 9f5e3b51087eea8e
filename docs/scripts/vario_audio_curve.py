"""The vario audio's curve as a figure (docs/flight-instrument.md, "Vario audio").

Usage::

    .venv/bin/python docs/scripts/vario_audio_curve.py [-o FIGURE.png] [--flight]

Left: pitch (Hz) against climb rate (m/s) with the default curve (the profile's ``audio:``
section defaults): silence in the dead band, the continuous sink tone below it, the
optional sink alarm's two pitches (drawn at -5 m/s). Middle: beep period and on-time
against climb (the beep table, 40 ms ticks). Right: the climb the tones follow after a step
from 0 to 2 m/s, for damping time constants 0, 0.5, 1.5 and 4 s, with the climb threshold.
Every value is computed by imuhal's own ``VarioAudioSettings`` and ``ToneGenerator``; the
script also prints the click measure of the tests (energy > 1 kHz from the pitch around
each tone edge) for 5 ms ramps and for a hard gate; ``--flight`` adds the seed GPS vario's
60 s `thermal` flight through the audio sink, both ways.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from imuhal.offline.plotting import plot_vario_audio
from imuhal.sinks.flight.audio import ToneGenerator, VarioAudioSettings

OUT = Path(__file__).resolve().parents[1] / "images" / "vario-audio-curve.png"


def edge_splatter_db(settings: VarioAudioSettings, climb: float) -> float:
    """Worst energy farther than 1 kHz from the pitch, relative to all, in 20 ms windows
    centred on the start and stop of a 1 s tone between silences (dB)."""
    g = ToneGenerator(settings)
    pcm = np.concatenate([g.render(None, 0.1), g.render(climb, 1.03),
                          g.render(None, 0.3)]).astype(float)
    loud = np.convolve(pcm != 0, np.ones(32), mode="same") > 0
    edges = np.nonzero(np.diff(loud.astype(int)))[0] + 1
    rate = settings.sample_rate_hz
    worst = -np.inf
    for e in edges:
        if 160 <= e <= len(pcm) - 160:
            seg = pcm[e - 160:e + 160] * np.hanning(320)
            spec = np.abs(np.fft.rfft(seg)) ** 2
            f = np.fft.rfftfreq(320, 1 / rate)
            far = np.abs(f - f[np.argmax(spec)]) > 1000
            worst = max(worst, 10 * np.log10(spec[far].sum() / spec.sum()))
    return float(worst)


def flight_edges(ramp_s: float, seconds: float = 60.0) -> tuple[int, int, float]:
    """The seed GPS vario's `thermal` flight (seed 1) through the audio sink: (tone edges,
    edges above -50 dB, worst dB)."""
    import tempfile
    import wave

    from imuhal.emulation import open_emulated
    from imuhal.plugins.manager import load_registry
    from imuhal.profile.bundled import bundled_profiles
    from imuhal.profile.loader import load_profile
    from imuhal.sinks.flight.audio import AudioSink

    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    curve = profile.audio.model_copy(update={"ramp_s": ramp_s})
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "thermal.wav"
        sink = AudioSink({"curve": curve, "wav": str(out)})
        with open_emulated(profile, registry, scenario="thermal", seed=1) as pipeline:
            pipeline.run(seconds, [sink])
        with wave.open(str(out), "rb") as w:
            pcm = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2").astype(float)
    loud = np.convolve(pcm != 0, np.ones(32), mode="same") > 0
    edges = [e for e in np.nonzero(np.diff(loud.astype(int)))[0] + 1
             if 160 <= e <= len(pcm) - 160]
    rate = curve.sample_rate_hz
    values = []
    for e in edges:
        seg = pcm[e - 160:e + 160] * np.hanning(320)
        spec = np.abs(np.fft.rfft(seg)) ** 2
        f = np.fft.rfftfreq(320, 1 / rate)
        far = np.abs(f - f[np.argmax(spec)]) > 1000
        values.append(10 * np.log10(spec[far].sum() / spec.sum()))
    return len(values), sum(v > -50 for v in values), max(values)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-o", "--output", type=Path, default=OUT)
    parser.add_argument("--flight", action="store_true",
                        help="also fly 60 s of `thermal` and measure every tone edge")
    args = parser.parse_args(argv)
    figure = plot_vario_audio(VarioAudioSettings())
    args.output.parent.mkdir(parents=True, exist_ok=True)
    figure.save(args.output)
    print(f"wrote {args.output}")
    for name, settings in (("5 ms raised-cosine ramps", VarioAudioSettings()),
                           ("hard gate (one sample)", VarioAudioSettings(ramp_s=1 / 16000))):
        worst = max(edge_splatter_db(settings, x) for x in (0.6, 1.5, 3.0, 6.5, 9.5, -4.0))
        print(f"{name}: worst energy > 1 kHz from the pitch at a tone edge {worst:.1f} dB")
        if args.flight:
            n, clicks, worst = flight_edges(settings.ramp_s)
            print(f"  thermal 60 s: {n} tone edges, {clicks} above -50 dB, worst {worst:.1f} dB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
