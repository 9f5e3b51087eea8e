"""Vario audio: pitch and cadence of the generated samples against the curve, no clicks at
any tone start or stop (the spectrum around every edge), damping, sink alarm, silence while
the vario settles, and the `thermal` flight's WAV (beeps while the true climb exceeds the
threshold, silent on the ground from power-up, no click anywhere)."""

from __future__ import annotations

import wave
from pathlib import Path

import numpy as np
import pytest

from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
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


SPLATTER_LIMIT_DB = -50.0
"""A click is broadband: the energy farther than 1 kHz from the tone's pitch in a 20 ms
window centred on a tone's start or stop, relative to the window's energy. A hard gate gives
-16 dB; the 5 ms raised-cosine ramps give -63 dB (docs/flight-instrument.md)."""


def splatter_db(pcm: np.ndarray, edge: int, width: int = 320, guard_hz: float = 1000.0
                ) -> float:
    seg = pcm[edge - width // 2:edge + width // 2].astype(float)
    spec = np.abs(np.fft.rfft(seg * np.hanning(len(seg)))) ** 2
    f = np.fft.rfftfreq(len(seg), 1 / RATE)
    peak = f[np.argmax(spec)]
    return float(10 * np.log10(spec[np.abs(f - peak) > guard_hz].sum() / spec.sum()))


def worst_edge_db(pcm: np.ndarray) -> tuple[float, int]:
    """(worst splatter over every tone start and stop, number of edges measured)."""
    edges = [e for a, b in on_intervals(pcm) for e in (a, b) if 160 <= e <= len(pcm) - 160]
    return max(splatter_db(pcm, e) for e in edges), len(edges)


def _beeps_between_silences(settings: VarioAudioSettings, climb: float) -> np.ndarray:
    g = ToneGenerator(settings)
    return np.concatenate([g.render(None, 0.1), g.render(climb, 1.03), g.render(None, 0.3)])


@pytest.mark.parametrize("climb", [0.6, 1.5, 3.0, 6.5, 9.5, -4.0, -8.0])
def test_every_tone_starts_and_stops_without_a_click(climb: float) -> None:
    """Beeps, the sink tone, and a tone cut mid-beep by a return to the dead band."""
    worst, edges = worst_edge_db(_beeps_between_silences(VarioAudioSettings(), climb))
    assert edges >= 2 and worst < SPLATTER_LIMIT_DB


def test_the_click_measure_catches_a_hard_gate() -> None:
    hard = VarioAudioSettings(ramp_s=1 / RATE)  # one sample: the old generator's gate
    worst, _ = worst_edge_db(_beeps_between_silences(hard, 3.0))
    assert worst > -25.0


def test_pitch_changes_keep_the_phase() -> None:
    """Between two climb rates in the same beep the waveform goes on without a jump: the
    largest sample step stays that of the higher pitch's sine."""
    s = VarioAudioSettings()
    g = ToneGenerator(s)
    pcm = np.concatenate([g.render(9.5, 0.013), g.render(9.6, 0.013)]).astype(float)
    biggest_step = 2 * np.pi * s.climb_hz(9.6) / RATE * s.volume * 32767
    assert np.max(np.abs(np.diff(pcm[80:]))) <= biggest_step * 1.01


def test_the_sink_alarm_warbles_between_its_two_pitches_below_its_rate() -> None:
    s = VarioAudioSettings(sink_alarm_m_s=-5.0)
    pcm = ToneGenerator(s).render(-6.0, 1.0)
    half = int(s.sink_alarm_period_s / 2 * RATE)
    pitches = [frequency_hz(pcm[k * half + 80:(k + 1) * half - 80]) for k in range(8)]
    low, high = s.sink_alarm_hz
    assert pitches == pytest.approx([low, high] * 4, rel=0.02)
    assert len(on_intervals(pcm)) == 1  # one continuous sound
    assert frequency_hz(ToneGenerator(s).render(-4.0, 1.0)) == pytest.approx(
        s.sink_tone_hz(-4.0), rel=0.01)  # above the alarm rate: the sink tone


def _estimates(climbs: list[float], dt_s: float = 0.02) -> list[VerticalEstimate]:
    return [VerticalEstimate(t_ns=round(k * dt_s * 1e9), source="vario", altitude_m=0.0,
                             climb_m_s=c) for k, c in enumerate(climbs)]


def _sink_pcm(tmp_path: Path, curve: VarioAudioSettings, climbs: list[float]) -> np.ndarray:
    out = tmp_path / "a.wav"
    sink = AudioSink({"curve": curve, "wav": str(out)})
    for e in _estimates(climbs):
        sink.handle(e)
    sink.close()
    with wave.open(str(out), "rb") as w:
        return np.frombuffer(w.readframes(w.getnframes()), dtype="<i2")


@pytest.mark.parametrize("tau", [0.0, 0.5, 2.0, 4.0])
def test_damping_delays_the_first_beep_by_the_documented_time(tmp_path: Path, tau: float
                                                             ) -> None:
    """A step from 0 to 2 m/s at 3 s (the vario settled on the ground before it): the
    damped climb 2 (1 - exp(-t / tau)) crosses the 0.5 m/s threshold after
    tau ln(2 / 1.5), and the first beep starts there (within one 20 ms estimate)."""
    curve = VarioAudioSettings(damping_s=tau)
    climbs = [0.0] * 150 + [2.0] * 600
    pcm = _sink_pcm(tmp_path, curve, climbs)
    first = on_intervals(pcm)[0][0] / RATE
    expected = 3.0 + tau * np.log(2.0 / 1.5)
    assert first == pytest.approx(expected, abs=0.021)


def test_no_tone_while_the_vario_settles_at_power_up(tmp_path: Path) -> None:
    """A start-up transient (0.8 m/s for 1 s, as a filter converging on the ground shows) is
    silent; the tones come on after a second in the dead band."""
    climbs = [0.8] * 50 + [0.0] * 100 + [1.5] * 100
    pcm = _sink_pcm(tmp_path, VarioAudioSettings(), climbs)
    beeps = on_intervals(pcm)
    assert beeps and beeps[0][0] / RATE == pytest.approx(3.0, abs=0.021)


def test_a_start_in_the_air_sounds_after_settle_max(tmp_path: Path) -> None:
    curve = VarioAudioSettings(settle_max_s=2.0)
    pcm = _sink_pcm(tmp_path, curve, [1.5] * 200)
    assert on_intervals(pcm)[0][0] / RATE == pytest.approx(2.0, abs=0.021)


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
    # From power-up: in its first second the vario filter settles (its climb estimate
    # reaches 0.64 m/s on the ground) and the tones wait for it.
    first_second = pcm[:RATE]
    assert not np.any(first_second)
    for second in range(int(t0) + 1, 59):
        window = pcm[int((second - t0) * RATE):int((second + 1 - t0) * RATE)]
        climbs = [scenario.truth(second + k / 10).climb_m_s for k in range(11)]
        speed = np.linalg.norm(scenario.truth(second).velocity_ned_m_s)
        if max(abs(c) for c in climbs) < 0.05 and speed < 0.1:
            ground.append(np.any(window))
        elif min(climbs) > threshold + 0.5:  # clearly above: the filter has caught up
            climbing.append(len(on_intervals(window)))
    assert ground and not any(ground), "sound on the ground"
    assert climbing and min(climbing) >= 1, "a climbing second without a beep"
    worst, edges = worst_edge_db(pcm)
    assert edges > 100 and worst < SPLATTER_LIMIT_DB, f"a click of {worst:.1f} dB"


@pytest.mark.parametrize(("flags", "message"), [
    (["--audio-damping", "-1"], "--audio-damping -1.0: a time constant of 0 to 10 s"),
    (["--audio-sink-alarm", "2"], "--audio-sink-alarm 2.0: audio sink_alarm_m_s 2.0 must be"),
])
def test_audio_flags_out_of_range_are_one_line_errors(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], flags: list[str], message: str
        ) -> None:
    from imuhal.cli.main import main

    # --skip-calibration: the calibration an emulated run makes first (seconds of CPU, tested
    # in tests/calibration) is not what is checked
    assert main(["run", "--emulate", "thermal", "--skip-calibration", "--duration", "1",
                 "--quiet", "--audio-wav", str(tmp_path / "a.wav"), *flags]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1] and not (tmp_path / "a.wav").exists()


@pytest.mark.slow
def test_audio_damping_from_the_command_line_reaches_the_tones(tmp_path: Path) -> None:
    """`--audio-damping 4` delays the `thermal` flight's first beep (16 s without damping)."""
    from imuhal.cli.main import main

    firsts = []
    for damping in ("0", "4"):
        out = tmp_path / f"d{damping}.wav"
        # both uncalibrated (--skip-calibration: seconds of CPU each, tested in
        # tests/calibration): what is compared is the damping's delay
        assert main(["run", "--emulate", "thermal", "--skip-calibration", "--duration", "22",
                     "--quiet", "--audio-wav", str(out), "--audio-damping", damping]) == 0
        with wave.open(str(out), "rb") as w:
            pcm = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2")
        firsts.append(on_intervals(pcm)[0][0] / RATE)
    assert firsts[1] > firsts[0] + 0.5


def test_the_curve_figure_draws_the_settings_pitch_and_cadence(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib", reason="the plot extra (matplotlib) is not installed")
    from imuhal.offline.plotting import plot_vario_audio

    s = VarioAudioSettings()
    figure = plot_vario_audio(s)
    assert set(figure.axes) == {"pitch", "cadence", "damping"}
    x, y = figure.axes["pitch"].lines[0].get_data()
    assert list(y) == [s.climb_hz(c) for c in x]
    assert figure.save(tmp_path / "curve.png").stat().st_size > 10_000
