"""Walks, floors and plans as numpy arrays: shapes, dtypes, round trips."""

import numpy as np
import pytest

import wipdr
from conftest import DATA, FIXTURE_FLOOR

WALK_FILE = FIXTURE_FLOOR / "path_data_files" / "sim_F1_w0000.txt.gz"


def test_read_walk_gives_float64_arrays_of_the_documented_shapes():
    w = wipdr.read_walk(WALK_FILE)
    assert w.id == "sim_F1_w0000"
    assert w.waypoints.dtype == np.float64 and w.waypoints.ndim == 2 and w.waypoints.shape[1] == 3
    assert len(w.waypoints) > 10
    for name in ["accelerometer", "gyroscope", "magnetometer", "rotation_vector"]:
        a = getattr(w, name)
        assert a.dtype == np.float64 and a.shape[1] == 4, name
        assert len(a) > 1000, name
        assert np.all(np.diff(a[:, 0]) >= 0), f"{name} sorted by time"
    assert w.pressure.shape == (0, 2)
    t, entries = w.scans[0]
    assert isinstance(t, int) and len(entries) > 0
    bssid, rssi = entries[0]
    assert isinstance(bssid, str) and len(bssid) == 17 and -120.0 <= rssi <= 0.0
    assert len(w.scans_with_times[0][1][0]) == 3
    assert w.metadata["start_time"] == 1600000000000
    assert w.waypoint_floors == [None] * len(w.waypoints)
    # 50 Hz, as the fixtures say.
    rate = (len(w.accelerometer) - 1) / ((w.accelerometer[-1, 0] - w.accelerometer[0, 0]) / 1000.0)
    assert 45.0 < rate < 55.0


def test_a_walk_built_from_arrays_gives_back_the_same_arrays():
    w = wipdr.read_walk(WALK_FILE)
    w2 = wipdr.Walk(
        w.id,
        w.waypoints,
        accelerometer=w.accelerometer,
        gyroscope=w.gyroscope.tolist(),
        rotation_vector=w.rotation_vector,
        scans=w.scans_with_times,
        metadata={"model": "Pixel", "route": "Trial01", "start_time": 5},
    )
    np.testing.assert_array_equal(w2.waypoints, w.waypoints)
    np.testing.assert_array_equal(w2.accelerometer, w.accelerometer)
    np.testing.assert_array_equal(w2.gyroscope, w.gyroscope)
    assert w2.magnetometer.shape == (0, 4)
    assert w2.scans_with_times == w.scans_with_times
    assert w2.metadata["route"] == "Trial01" and w2.metadata["start_time"] == 5


def test_walk_streams_are_sorted_on_construction():
    w = wipdr.Walk("w", [[2000, 1.0, 1.0], [1000, 0.0, 0.0]], waypoint_floors=[1, None])
    np.testing.assert_array_equal(w.waypoints[:, 0], [1000.0, 2000.0])
    assert w.waypoint_floors == [None, 1]


def test_read_floor_gives_plan_walks_and_folds():
    floor = wipdr.read_floor(FIXTURE_FLOOR)
    assert len(floor) == 10 and floor.name == "sim/F1"
    assert floor.walk_ids == sorted(floor.walk_ids)
    assert floor.folds() == [i % 5 for i in range(10)]
    assert (floor.plan.width, floor.plan.height) == pytest.approx((120.0, 80.0))
    assert floor.plan.walls.shape[1] == 4 and len(floor.plan.walls) > 100
    assert all(p.shape[1] == 2 for p in floor.plan.outline)
    assert floor.walk("sim_F1_w0003").id == "sim_F1_w0003"
    assert floor.skipped_walks == []
    with pytest.raises(KeyError):
        floor.walk("nope")


@pytest.mark.skipif(not (DATA / "ipin2023").is_dir(), reason=f"IPIN data not found under {DATA} (set WIPDR_DATA to the data root)")
def test_read_walk_reads_an_ipin_logfile_with_floors():
    trials = DATA / "ipin2023" / "trials"
    path = sorted(trials.glob("*.txt*"))[0]
    w = wipdr.read_walk(path)
    assert len(w.waypoints) > 10
    assert all(f is not None for f in w.waypoint_floors)
    assert w.pressure.shape[1] == 2 and len(w.pressure) > 100
    assert w.metadata["route"] is not None
