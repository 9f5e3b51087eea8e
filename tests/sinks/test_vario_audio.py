"""Vario audio: pitch and cadence of the generated samples against the curve, and the
`thermal` flight's WAV (beeps while the true climb exceeds the threshold, silent on the
ground)."""

from __future__ import annotations

import wave
from pathlib import Path

import numpy as np
import pytest

from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile
from imuhal.profiles_dir import bundled_profiles
from imuhal.sinks.flight.audio import AudioSink, ToneGenerator, VarioAudioSettings

RATE = 16000


def frequency_hz(pcm: np.ndarray) -> float:
    """Pitch from rising zero crossings (independent of the generator's phase arithmetic)."""
    x = pcm.astype(float)
    rising = np.nonzero((x[:-1] <= 0) & (x[1:] > 0))[0]
    if len(rising) < 2:
        return 0.0
    return (len(rising) - 1) / ((rising[-1] - rising[0]) / RATE)


def on_intervals(pcm: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) sample indices of the stretches with sound."""
    loud = np.abs(pcm.astype(float)) > 0
    # bridge the zero crossings inside a tone: a gap shorter than 2 ms is not silence
    k = int(0.002 * RATE)
    smeared = np.convolve(loud, np.ones(k), mode="same") > 0
    edges = np.diff(smeared.astype(int))
    starts = list(np.nonzero(edges == 1)[0] + 1)
    ends = list(np.nonzero(edges == -1)[0] + 1)
    if smeared[0]:
        starts.insert(0, 0)
    if smeared[-1]:
        ends.append(len(pcm))
    return list(zip(starts, ends, strict=True))


@pytest.mark.parametrize("climb", [0.6, 1.5, 3.0, 4.0, 6.5, 9.5])
def test_climb_beeps_have_the_curves_pitch_and_cadence(climb: float) -> None:
    s = VarioAudioSettings()
    pcm = ToneGenerator(s).render(climb, 4.0)
    period, on = s.beep(climb)
    beeps = on_intervals(pcm)
    full = beeps[:-1]  # the last may be cut by the end of the buffer
    assert len(full) >= 4
    starts = np.array([a for a, _ in full]) / RATE
    assert np.diff(starts) == pytest.approx(period, abs=0.002)  # 2 ms: the smearing above
    assert [(b - a) / RATE for a, b in full] == pytest.approx([on] * len(full), abs=0.004)
    assert frequency_hz(pcm[full[0][0]:full[0][1]]) == pytest.approx(s.climb_hz(climb), rel=0.01)


def test_pitch_rises_and_beeps_quicken_with_the_climb() -> None:
    s = VarioAudioSettings()
    climbs = [0.5, 1, 2, 4, 7, 10]
    pitches = [s.climb_hz(c) for c in climbs]
    periods = [s.beep(c)[0] for c in climbs]
    assert pitches == sorted(pitches) and pitches[0] == 200 and pitches[-1] == 3200
    assert s.climb_hz(4.0) == 1600  # the crossover
    assert periods == sorted(periods, reverse=True) and periods[0] > periods[-1]


def test_strong_sink_is_a_continuous_low_tone() -> None:
    s = VarioAudioSettings()
    pcm = ToneGenerator(s).render(-4.0, 2.0)
    assert len(on_intervals(pcm)) == 1
    f = frequency_hz(pcm)
    assert f == pytest.approx(s.sink_tone_hz(-4.0), rel=0.01)
    assert s.min_hz <= f < s.sink_hz


@pytest.mark.parametrize("climb", [-2.4, -1.0, 0.0, 0.49])
def test_the_dead_band_is_silent(climb: float) -> None:
    assert not np.any(ToneGenerator().render(climb, 1.0))


def test_a_custom_curve_from_the_profile_moves_the_thresholds() -> None:
    s = VarioAudioSettings(climb_threshold_m_s=0.2, sink_threshold_m_s=-1.5)
    assert np.any(ToneGenerator(s).render(0.3, 1.0))
    assert np.any(ToneGenerator(s).render(-1.6, 0.5))
    with pytest.raises(ValueError, match="sink_threshold < climb_threshold"):
        VarioAudioSettings(climb_threshold_m_s=-3.0)


@pytest.mark.slow
def test_the_thermal_wav_beeps_in_the_climb_and_is_silent_on_the_ground(tmp_path: Path
                                                                         ) -> None:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    out = tmp_path / "thermal.wav"
    sink = AudioSink({"curve": profile.audio, "wav": str(out)})
    estimates: list[VerticalEstimate] = []
    with open_emulated(profile, registry, scenario="thermal") as pipeline:
        scenario = pipeline.board.scenario
        for event in pipeline.events(60.0):
            sink.handle(event)
            if isinstance(event, VerticalEstimate) and event.source == sink.source:
                estimates.append(event)
    sink.close()
    with wave.open(str(out), "rb") as w:
        assert (w.getnchannels(), w.getsampwidth(), w.getframerate()) == (1, 2, RATE)
        pcm = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2")
    t0 = estimates[0].t_ns / 1e9  # the WAV starts at the first estimate
    threshold = profile.audio.climb_threshold_m_s
    ground, climbing = [], []
    # From 2 s after the first estimate: in its first second the vario filter is still
    # settling (its climb estimate reaches 0.64 m/s on the ground), and the tones say so.
    for second in range(int(t0) + 2, 59):
        window = pcm[int((second - t0) * RATE):int((second + 1 - t0) * RATE)]
        climbs = [scenario.truth(second + k / 10).climb_m_s for k in range(11)]
        speed = np.linalg.norm(scenario.truth(second).velocity_ned_m_s)
        if max(abs(c) for c in climbs) < 0.05 and speed < 0.1:
            ground.append(np.any(window))
        elif min(climbs) > threshold + 0.5:  # clearly above: the filter has caught up
            climbing.append(len(on_intervals(window)))
    assert ground and not any(ground), "sound on the ground"
    assert climbing and min(climbing) >= 1, "a climbing second without a beep"
