"""``imuhal plot``: the figure's series are the log's and the truth's (checked on the Line2D
data, not on pixels)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from imuhal.cli.main import main

pytest.importorskip("matplotlib", reason="plots need the 'plot' extra (in the test extra)")

from imuhal.offline.plotting import Truth, plot_log, read_log, read_truth


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("plot")
    log, truth = folder / "log.csv", folder / "truth.csv"
    assert main(["run", "profiles/seed-rc-vario.yaml", "--emulate", "rc-flight", "--duration",
                 "8", "--quiet", "--output", str(log), "--samples", "--truth", str(truth)]) == 0
    return log, truth


def _column(log: Path, source: str, column: str) -> tuple[np.ndarray, np.ndarray]:
    with log.open(newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["source"] == source and r[column]]
    return np.array([float(r["t_s"]) for r in rows]), np.array([float(r[column]) for r in rows])


def _line(ax: object, label: str) -> tuple[np.ndarray, np.ndarray]:
    for line in ax.get_lines():  # type: ignore[attr-defined]
        if line.get_label() == label:
            return np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
    raise AssertionError(f"no line {label!r}")


def test_plot_writes_a_png_with_every_panel(run: tuple[Path, Path], tmp_path: Path) -> None:
    log, truth = run
    figure = tmp_path / "flight.png"
    assert main(["plot", str(log), "--truth", str(truth), "-o", str(figure)]) == 0
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_plotted_attitude_and_vertical_series_are_the_logs(run: tuple[Path, Path]) -> None:
    log, truth = run
    fig = plot_log(read_log(log), read_truth(truth))
    assert set(fig.axes) >= {"attitude", "attitude error", "altitude", "climb",
                             "vertical error", "accel", "gyro", "mag", "pressure", "flags",
                             "sample rate"}
    for panel, source, column in (("attitude", "ahrs", "roll_deg"),
                                  ("attitude", "ahrs", "yaw_deg"),
                                  ("altitude", "vario", "altitude_m"),
                                  ("climb", "vario", "climb_m_s"),
                                  ("gyro", "imu", "gz_rad_s"),
                                  ("pressure", "baro", "pressure_pa")):
        x, y = _line(fig.axes[panel], f"{source} {column}")
        # NaN breaks are not log values: the +/-180 wraps of an angle, and the rows of an
        # estimate withheld (a vario's first rows, until it has settled) drawn as a gap
        x, y = x[~np.isnan(y)], y[~np.isnan(y)]
        t, v = _column(log, source, column)
        np.testing.assert_array_equal(x, t)
        np.testing.assert_array_equal(y, v)


def test_the_truth_is_overlaid_and_the_error_is_estimate_minus_truth(
        run: tuple[Path, Path]) -> None:
    log, truth_path = run
    truth = read_truth(truth_path)
    fig = plot_log(read_log(log), truth)
    x, y = _line(fig.axes["climb"], "truth climb_m_s")
    np.testing.assert_array_equal(x, truth.t_s)
    np.testing.assert_array_equal(y, truth.columns["climb_m_s"])
    # The truth file has a row at every estimate's time: the error there is exact.
    t, climb = _column(log, "vario", "climb_m_s")
    ex, ey = _line(fig.axes["vertical error"], "vario climb_m_s error")
    ex, ey = ex[~np.isnan(ey)], ey[~np.isnan(ey)]  # withheld rows are gaps, as above
    true_at = dict(zip(np.round(truth.t_s, 6), truth.columns["climb_m_s"], strict=True))
    np.testing.assert_array_equal(ex, t)
    np.testing.assert_allclose(ey, climb - np.array([true_at[round(s, 6)] for s in t]),
                               atol=1e-12)
    _, yaw_error = _line(fig.axes["attitude error"], "ahrs yaw_deg error")
    assert np.nanmax(np.abs(yaw_error)) <= 180.0


def test_device_health_counts_flagged_samples_per_flag(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    with log.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "source", "kind", "flags", "pressure_pa"])
        for i in range(300):
            flags = 32 if i in (50, 51, 200) else 0  # three stale samples
            w.writerow([f"{i * 0.01:.6f}", "baro", "pressure", flags, 100000.0])
    fig = plot_log(read_log(log))
    t, count = _line(fig.axes["flags"], "baro STALE")
    assert count[-1] == 3 and t[np.argmax(count == 1)] == pytest.approx(0.5)
    _, rate = _line(fig.axes["sample rate"], "baro samples/s")
    assert list(rate) == [100, 100]


def test_plot_refuses_to_overwrite_its_input(run: tuple[Path, Path],
                                             capsys: pytest.CaptureFixture[str]) -> None:
    log, _ = run
    before = log.read_bytes()
    assert main(["plot", str(log), "-o", str(log)]) == 2
    assert "would destroy the input" in capsys.readouterr().err
    assert log.read_bytes() == before


def test_an_unknown_figure_format_is_one_clear_error(run: tuple[Path, Path], tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]
                                                     ) -> None:
    assert main(["plot", str(run[0]), "-o", str(tmp_path / "fig.jpgg")]) == 2
    assert "unknown figure format" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_events_in_memory_plot_as_their_csv_log_does(tmp_path: Path) -> None:
    from imuhal.emulation import open_emulated
    from imuhal.offline.plotting import log_from_events
    from imuhal.pipeline import CsvSink
    from imuhal.plugins.manager import load_registry
    from imuhal.profile.loader import load_profile

    registry = load_registry()
    profile = load_profile("profiles/gy91.yaml", registry)
    events: list[object] = []
    with open_emulated(profile, registry, scenario="static") as pipeline:
        sink = CsvSink(tmp_path / "log.csv", include_samples=True)
        for event in pipeline.events(2.0):
            events.append(event)
            sink.handle(event)
        sink.close()
    from_memory = log_from_events(events)  # type: ignore[arg-type]
    from_file = read_log(tmp_path / "log.csv")
    assert from_memory.series.keys() == from_file.series.keys()
    for key, series in from_file.series.items():
        np.testing.assert_array_equal(from_memory.series[key].t_s, series.t_s)
        assert from_memory.series[key].columns.keys() == series.columns.keys()
        for name, values in series.columns.items():
            np.testing.assert_array_equal(from_memory.series[key].columns[name], values)


def test_a_log_in_another_frame_plots_its_own_columns_and_refuses_ned_truth(
        run: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "enu.csv"
    assert main(["run", "profiles/seed-rc-vario.yaml", "--emulate", "rc-flight", "--duration",
                 "3", "--quiet", "--output", str(log), "--output-frame", "enu"]) == 0
    fig = plot_log(read_log(log))
    x, y = _line(fig.axes["attitude"], "ahrs roll_deg")
    t, v = _column(log, "ahrs", "roll_deg_enu")
    np.testing.assert_array_equal(x, t)
    np.testing.assert_array_equal(y, v)
    assert main(["plot", str(log), "--truth", str(run[1]), "-o", str(tmp_path / "f.png")]) == 2
    assert "truth files are ned" in capsys.readouterr().err


def test_the_output_of_imuhal_estimate_plots_as_one_source(run: tuple[Path, Path],
                                                           tmp_path: Path) -> None:
    out = tmp_path / "mahony.csv"
    assert main(["estimate", "mahony", str(run[0]), "-o", str(out)]) == 0
    fig = plot_log(read_log(out))
    x, y = _line(fig.axes["attitude"], "mahony pitch_deg")
    with out.open(newline="") as f:
        rows = list(csv.DictReader(f))
    np.testing.assert_array_equal(x, [float(r["t_s"]) for r in rows])
    np.testing.assert_array_equal(y, [float(r["pitch_deg"]) for r in rows])


def test_yaw_error_across_north_is_the_short_way_round() -> None:
    from imuhal.offline.plotting import Series, Truth, errors

    t = np.array([0.0, 1.0, 2.0])
    estimate = Series(t, {"yaw_deg": np.array([179.0, -179.0, 178.0])}, np.zeros(3))
    truth = Truth(t, {"yaw_deg": np.array([-179.0, 179.0, 178.5])})
    np.testing.assert_allclose(errors(estimate, truth, "yaw_deg"), [-2.0, 2.0, -0.5])


def test_truth_yaw_is_interpolated_across_north_not_through_south() -> None:
    from imuhal.offline.plotting import Series, Truth, errors

    truth = Truth(np.array([0.0, 1.0]), {"yaw_deg": np.array([179.0, -179.0])})
    estimate = Series(np.array([0.5]), {"yaw_deg": np.array([-180.0])}, np.zeros(1))
    np.testing.assert_allclose(errors(estimate, truth, "yaw_deg"), [0.0], atol=1e-9)


def test_yaw_crossing_180_breaks_the_line_instead_of_a_vertical_stroke(tmp_path: Path) -> None:
    log = tmp_path / "est.csv"
    yaw = [170.0, 178.0, -178.0, -170.0, -178.0, 179.0]
    log.write_text("t_s,qw,roll_deg,pitch_deg,yaw_deg\n" + "".join(
        f"{i * 0.1:.1f},1,0,0,{y}\n" for i, y in enumerate(yaw)))
    truth = Truth(np.array([0.0, 0.5]), {"yaw_deg": np.array([175.0, -175.0]),
                                         "roll_deg": np.zeros(2), "pitch_deg": np.zeros(2),
                                         "climb_m_s": np.zeros(2)})
    fig = plot_log(read_log(log), truth)
    x, y = _line(fig.axes["attitude"], "est yaw_deg")
    # A NaN between the samples of each wrap (178 -> -178, -178 -> 179), the samples kept.
    np.testing.assert_array_equal(np.isnan(y), [False, False, True, False, False, False,
                                                True, False])
    np.testing.assert_array_equal(y[~np.isnan(y)], yaw)
    np.testing.assert_allclose(x[np.isnan(y)], [0.15, 0.45])
    tx, ty = _line(fig.axes["attitude"], "truth yaw_deg")
    np.testing.assert_array_equal(tx, [0.0, 0.25, 0.5])
    np.testing.assert_array_equal(ty, [175.0, np.nan, -175.0])
    x, y = _line(fig.axes["attitude"], "est roll_deg")  # nothing wraps: drawn as logged
    np.testing.assert_array_equal(y, np.zeros(len(yaw)))
