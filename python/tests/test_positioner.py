"""The Positioner fed one sample at a time from Python against `wipdr.locate` and the
CLI's `wipdr locate`."""

import csv

import numpy as np
import pytest

import wipdr
from conftest import FIXTURE_FLOOR, push_all, run_cli


@pytest.fixture(scope="module")
def floor():
    return wipdr.read_floor(FIXTURE_FLOOR)


def split(floor, index):
    """Walk `index` and the walks of the other protocol folds (its training walks)."""
    folds = floor.folds()
    walks = floor.walks
    training = [w for w, f in zip(walks, folds) if f != folds[index]]
    return walks[index], training


def assert_tracks_equal(a, b):
    assert a.shape == b.shape, (a.shape, b.shape)
    np.testing.assert_array_equal(a, b)  # NaN equals NaN here (floor, sd_m unknown)


@pytest.mark.parametrize("scheme", ["wifi", "ekf", "pdr", "pf", "apf", "pmf"])
def test_a_positioner_fed_sample_by_sample_equals_locate(floor, scheme):
    walk, training = split(floor, 1)
    training = wipdr.Floor(training, plan=floor.plan, name=floor.name)
    expected = wipdr.locate(walk, training, scheme)
    radio_map = wipdr.RadioMap.from_walks(training)
    start = (walk.waypoints[0, 0], walk.waypoints[0, 1], walk.waypoints[0, 2]) if scheme == "pdr" else None
    p = wipdr.Positioner(radio_map, scheme, floor_plan=floor.plan, stream_id=walk.id, start=start)
    n = push_all(p, walk)
    track = p.track()
    assert track.dtype == np.float64 and track.shape[1] == 5
    assert len(track) > 20
    assert n == p.counts()["samples"]
    assert_tracks_equal(track, expected)
    e = p.estimate()
    assert e is not None and np.isfinite([e.x, e.y]).all()


def test_locate_equals_the_cli(floor, wipdr_bin, tmp_path):
    walk, training = split(floor, 2)
    out = tmp_path / "track.csv"
    run_cli(wipdr_bin, "locate", "--data", FIXTURE_FLOOR, "--walk", walk.id, "--scheme", "ekf", "--out", out)
    with out.open() as f:
        rows = list(csv.DictReader(f))
    cli = np.array(
        [[float(r["t_ms"]), float(r["x"]), float(r["y"]), float(r["floor"] or "nan"), float(r["sd_m"] or "nan")] for r in rows]
    )
    py = wipdr.locate(walk, wipdr.Floor(training, plan=floor.plan, name=floor.name), "ekf")
    assert_tracks_equal(py, cli)


def test_push_returns_estimates_only_on_steps_and_fixes(floor):
    walk, training = split(floor, 0)
    p = wipdr.Positioner(wipdr.RadioMap.from_walks(training), "ekf")
    t, entries = walk.scans_with_times[0]
    e = p.push_scan(t, entries)
    assert e is not None and e.t_ms == t and e.sd_m is not None
    assert e.covariance is not None and len(e.covariance) == 2
    assert p.push_gyroscope(t + 1, 0.0, 0.0, 0.0) is None
    assert p.push_pressure(t + 2, 1000.0) is None
    assert p.counts()["scans"] == 1 and p.counts()["pressure"] == 1
    assert p.track().shape == (1, 5)


def test_a_radio_map_from_records_positions_a_stream():
    # Ten points along a corridor, two APs (as the Rust crate's example).
    positions = [[float(i), 0.0] for i in range(10)]
    scans = [[("00:00:00:00:00:01", -40.0 - 4.0 * i), (2, -76.0 + 4.0 * i)] for i in range(10)]
    rm = wipdr.RadioMap.from_records(positions, scans)
    assert len(rm) == 10 and rm.n_aps == 2 and rm.positions.shape == (10, 2)
    p = wipdr.Positioner(rm, "ekf")
    for k in range(200):
        t = 50 * k
        p.push_rotation_vector(t, 0.0, 0.0, 0.0)
        p.push_accelerometer(t, 0.0, 0.0, 9.81 + 3.0 * np.sin(t * 0.0126))
        if k % 40 == 0:
            p.push_scan(t, [("00:00:00:00:00:01", -48.0), ("00:00:00:00:00:02", -68.0)])
    e = p.estimate()
    assert p.counts()["scans"] == 5
    # -48 dBm from AP 1 and -68 from AP 2 is where i = 2 on the corridor.
    assert 0.0 <= e.x <= 5.0 and abs(e.y) < 1.0


def test_a_radio_map_from_records_keeps_floors():
    rm = wipdr.RadioMap.from_records(
        [[float(i), 0.0, i % 2] for i in range(6)], [[(1, -50.0 - i)] for i in range(6)]
    )
    assert rm.floors == [0, 1, 0, 1, 0, 1]


@pytest.mark.parametrize("scheme", ["ekf", "pmf"])
def test_smooth_is_the_offline_locate(floor, scheme):
    walk, training = split(floor, 1)
    training = wipdr.Floor(training, plan=floor.plan, name=floor.name)
    expected = wipdr.locate(walk, training, scheme, config={"offline": True})
    causal = wipdr.locate(walk, training, scheme)
    p = wipdr.Positioner(wipdr.RadioMap.from_walks(training), scheme, floor_plan=floor.plan, stream_id=walk.id)
    push_all(p, walk)
    smoothed = p.smooth()
    assert smoothed.dtype == np.float64 and smoothed.shape[1] == 5 and len(smoothed) > 20
    assert_tracks_equal(smoothed, expected)
    # Smoothing uses the later inputs: the track differs from the causal one.
    assert smoothed.shape != causal.shape or not np.array_equal(smoothed[:, 1:3], causal[:, 1:3])


def test_smooth_refuses_a_known_start(floor):
    walk, training = split(floor, 1)
    training = wipdr.Floor(training, plan=floor.plan, name=floor.name)
    start = (walk.waypoints[0, 0], walk.waypoints[0, 1], walk.waypoints[0, 2])
    p = wipdr.Positioner(wipdr.RadioMap.from_walks(training), "pdr", floor_plan=floor.plan, start=start)
    push_all(p, walk)
    with pytest.raises(ValueError, match="smooth"):
        p.smooth()


def test_a_site_model_saved_and_loaded_positions_as_before(floor, tmp_path):
    walk, training = split(floor, 1)
    model = wipdr.SiteModel.fit(wipdr.Floor(training, plan=floor.plan, name=floor.name))
    assert wipdr.RadioMap is wipdr.SiteModel
    path = tmp_path / "f1.wipdr"
    model.save(path)
    loaded = wipdr.SiteModel.load(path)
    assert len(loaded) == len(model) and loaded.n_aps == model.n_aps
    assert loaded.provenance["training_walks"] == len(training)
    tracks = []
    for m in (model, loaded):
        p = wipdr.Positioner(m, "pmf", stream_id=walk.id)
        push_all(p, walk)
        tracks.append(p.track())
    assert len(tracks[0]) > 20
    assert_tracks_equal(tracks[0], tracks[1])


def test_a_model_from_wipdr_fit_positions_as_locate_model(floor, wipdr_bin, tmp_path):
    walk = floor.walks[0]
    model_path = tmp_path / "f1.wipdr"
    run_cli(wipdr_bin, "fit", "--data", FIXTURE_FLOOR, "--out", model_path)
    walk_file = FIXTURE_FLOOR / "path_data_files" / f"{walk.id}.txt.gz"
    out = tmp_path / "track.csv"
    run_cli(wipdr_bin, "locate", "--model", model_path, walk_file, "--scheme", "ekf", "--out", out)
    with out.open() as f:
        rows = list(csv.DictReader(f))
    cli = np.array(
        [[float(r["t_ms"]), float(r["x"]), float(r["y"]), float(r["floor"] or "nan"), float(r["sd_m"] or "nan")] for r in rows]
    )
    p = wipdr.Positioner(wipdr.SiteModel.load(model_path), "ekf", stream_id=walk.id)
    push_all(p, walk)
    assert_tracks_equal(p.track(), cli)


def test_a_damaged_model_file_is_a_data_error(tmp_path):
    path = tmp_path / "bad.wipdr"
    path.write_bytes(b"WIPDRSM\0" + bytes(40))
    with pytest.raises(wipdr.DataError, match="bad.wipdr"):
        wipdr.SiteModel.load(path)
