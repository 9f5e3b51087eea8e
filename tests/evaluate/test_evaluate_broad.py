"""Reading BROAD-format recordings and evaluating them (synthetic trials, never BROAD's data)."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("h5py")
pytest.importorskip("scipy")

from tests.support.broad_synthetic import synthetic_trial, write_hdf5, write_mat, write_trials_json

from imuhal.cli.main import main
from imuhal.evaluate.download import download_broad
from imuhal.evaluate.recording import RecordingSource, read_broad
from imuhal.evaluate.runner import EstimatorSpec, evaluate_serial
from imuhal.plugins import load_registry


@pytest.fixture(scope="module")
def trial_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("broad")
    write_hdf5(d / "01_a.hdf5", synthetic_trial(seed=1))
    write_mat(d / "02_b.mat", synthetic_trial(seed=2))
    write_trials_json(d, {"01_a": ["all_trials", "undisturbed"],
                          "02_b": ["all_trials", "disturbed"]})
    return d


def test_hdf5_and_mat_forms_of_a_trial_read_identically(tmp_path):
    trial = synthetic_trial(seconds=1.0)
    a = read_broad(write_hdf5(tmp_path / "t.hdf5", trial))
    b = read_broad(write_mat(tmp_path / "t.mat", trial))
    np.testing.assert_array_equal(a.gyro_rad_s, b.gyro_rad_s)
    np.testing.assert_array_equal(a.q_truth, b.q_truth)
    np.testing.assert_array_equal(a.mask, b.mask)
    assert a.rate_hz == b.rate_hz == pytest.approx(285.714, abs=1e-3)


def test_broad_axes_become_ned_body_and_the_truth_follows(tmp_path):
    trial = synthetic_trial(seconds=0.5)
    rec = read_broad(write_hdf5(tmp_path / "t.hdf5", trial))
    # at rest the specific force points up: -z in NED body axes, rotated by the truth
    w, x, y, z = rec.q_truth[0]
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    np.testing.assert_allclose(r @ rec.accel_m_s2[0], [0, 0, -9.81], atol=0.1)


def test_groups_come_from_the_trials_index(trial_dir):
    assert read_broad(trial_dir / "02_b.mat").groups == ("all_trials", "disturbed")


def test_vqf_and_madgwick_track_a_clean_synthetic_trial(trial_dir):
    pytest.importorskip("vqf")
    results = evaluate_serial([RecordingSource(str(trial_dir / "01_a.hdf5"))],
                              [EstimatorSpec("vqf"), EstimatorSpec("madgwick", {}, 6)],
                              load_registry())
    for r in results:
        assert r.missing == 0
        assert r.inclination_deg < 1.0, r


def test_evaluate_command_writes_table_csv_and_json(trial_dir, tmp_path, capsys):
    out_csv, out_json, out_md = tmp_path / "r.csv", tmp_path / "r.json", tmp_path / "r.md"
    rc = main(["evaluate", str(trial_dir), "-e", "madgwick", "-e", "madgwick:beta=0.1",
               "--dof", "9", "-o", str(out_csv), "--json", str(out_json), "-q",
               "--group", "disturbed", "--markdown", str(out_md)])
    assert rc == 0
    table = capsys.readouterr().out
    assert "madgwick beta=0.1" in table and "group disturbed" in table
    data = json.loads(out_json.read_text())
    assert len(data["trials"]) == 4
    assert {g["group"] for g in data["groups"]} == {"all", "undisturbed", "disturbed"}
    assert out_csv.read_text().count("\n") == 5
    assert "| madgwick beta=0.1 |" in out_md.read_text()


def test_a_grid_runs_every_value(trial_dir, capsys):
    rc = main(["evaluate", str(trial_dir / "01_a.hdf5"), "-e", "madgwick", "--dof", "6",
               "--grid", "madgwick.beta=0.02,0.2", "-q"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "madgwick beta=0.02" in out and "madgwick beta=0.2" in out


def test_broad_before_its_download_is_a_one_line_error_naming_the_download(tmp_path, capsys):
    rc = main(["evaluate", "--broad", "--cache", str(tmp_path / "broad"), "-e", "madgwick"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert str(tmp_path / "broad") in err and "--download-broad" in err


def test_a_sample_csv_without_truth_is_a_one_line_error(tmp_path, capsys):
    samples = tmp_path / "s.csv"
    samples.write_text("t_s,gx_rad_s\n0,0\n")
    assert main(["evaluate", str(samples), "-e", "madgwick"]) == 2
    assert "--truth" in capsys.readouterr().err


def test_download_fetches_every_trial_into_the_cache(trial_dir, tmp_path):
    source = tmp_path / "remote"
    source.mkdir()
    write_hdf5(source / "01_a.hdf5", synthetic_trial(seconds=0.2))
    write_trials_json(source, {"01_a": ["all_trials"]})
    cache = download_broad(tmp_path / "cache", base_url=source.as_uri())
    assert read_broad(cache / "01_a.hdf5").name == "01_a"


def test_dask_gives_the_serial_results(trial_dir):
    pytest.importorskip("dask")
    from imuhal.evaluate.dask_runner import evaluate_dask

    sources = [RecordingSource(str(trial_dir / "01_a.hdf5")),
               RecordingSource(str(trial_dir / "02_b.mat"))]
    specs = [EstimatorSpec("madgwick"), EstimatorSpec("madgwick", {"beta": 0.1}, 6)]
    serial = evaluate_serial(sources, specs, load_registry())
    parallel = evaluate_dask(sources, specs, scheduler="threads")
    strip = [(r.trial, r.label, r.dof, r.total_deg, r.heading_deg, r.inclination_deg)
             for r in serial]
    assert strip == [(r.trial, r.label, r.dof, r.total_deg, r.heading_deg, r.inclination_deg)
                     for r in parallel]


def test_an_imuhal_sample_csv_with_truth_csv_evaluates_like_the_same_broad_trial(tmp_path):
    from imuhal.core.conventions import ENU, NED, VectorKind, convert_quat, vector_to_ned

    trial = synthetic_trial(seconds=2.0, seed=5)
    broad = RecordingSource(str(write_hdf5(tmp_path / "t.hdf5", trial)))
    n = len(trial["imu_gyr"])
    t = np.arange(n) / trial["sampling_rate"]
    cols = [vector_to_ned(trial["imu_gyr"], ENU, VectorKind.ANGULAR_RATE),
            vector_to_ned(trial["imu_acc"], ENU, VectorKind.SPECIFIC_FORCE),
            vector_to_ned(trial["imu_mag"], ENU, VectorKind.MAGNETIC_FIELD)]
    rows = np.column_stack([t, *cols])
    samples = tmp_path / "samples.csv"
    header = "t_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2,mx_ut,my_ut,mz_ut"
    samples.write_text(header + "\n" + "\n".join(",".join(repr(float(v)) for v in r)
                                                 for r in rows) + "\n")
    q = convert_quat(trial["opt_quat"], ENU, NED)
    truth = tmp_path / "truth.csv"
    truth.write_text("# imuhal-truth v1\nt_s,qw,qx,qy,qz\n" + "\n".join(
        ",".join(repr(float(v)) for v in (ti, *qi)) for ti, qi in zip(t, q, strict=True)) + "\n")
    from imuhal.evaluate.runner import estimate_quaternions

    a, b = broad.load(), RecordingSource(str(samples), str(truth)).load()
    np.testing.assert_allclose(b.q_truth, a.q_truth, atol=1e-12)
    spec = EstimatorSpec("madgwick")
    np.testing.assert_allclose(estimate_quaternions(b, spec, load_registry()),
                               estimate_quaternions(a, spec, load_registry()), atol=1e-9)
    # the CSV truth covers every row; BROAD's mask only its movement phase
    assert b.mask.all() and not a.mask.all()


def test_rate_settings_follow_the_recording_unless_given():
    from imuhal.evaluate.runner import with_rate_settings

    fields = {"sensor_rate_hz", "sample_period_s", "beta"}
    got = with_rate_settings(fields, {"beta": 0.1}, 250.0)
    assert got == {"beta": 0.1, "sensor_rate_hz": 250.0, "sample_period_s": 0.004}
    assert with_rate_settings(fields, {"sensor_rate_hz": 100.0}, 250.0)["sensor_rate_hz"] == 100.0


def test_freescale_tracks_a_recording_away_from_its_nominal_rate(trial_dir):
    results = evaluate_serial([RecordingSource(str(trial_dir / "01_a.hdf5"))],
                              [EstimatorSpec("freescale-6dof", {}, 6)], load_registry())
    assert results[0].inclination_deg < 2.0, results[0]
