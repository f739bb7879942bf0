"""Bad input raises the documented exception classes with the Rust error's message."""

import numpy as np
import pytest

import wipdr
from conftest import FIXTURE_FLOOR


def small_map():
    """Six survey points on a line, two APs (WKNN's default k is 5)."""
    return wipdr.RadioMap.from_records(
        [[float(i), 0.0] for i in range(6)], [[(1, -40.0 - 4 * i), (2, -70.0 + 4 * i)] for i in range(6)]
    )


def test_the_classes_are_oserror_and_valueerror():
    assert issubclass(wipdr.DataError, OSError) and issubclass(wipdr.DataError, wipdr.WipdrError)
    assert issubclass(wipdr.ConfigError, ValueError) and issubclass(wipdr.InputError, ValueError)


def test_a_missing_file_is_a_data_error(tmp_path):
    with pytest.raises(OSError, match="none.txt"):
        wipdr.read_walk(tmp_path / "none.txt")
    with pytest.raises(wipdr.DataError, match="not a folder"):
        wipdr.read_floor(tmp_path / "nofloor")
    with pytest.raises(wipdr.DataError, match="not a folder"):
        wipdr.evaluate([tmp_path / "nofloor"], ["ekf"])


def test_a_hostile_trace_names_file_and_line(tmp_path):
    bad = tmp_path / "long.txt"
    bad.write_text("#\tstartTime:1\n" + "1\tTYPE_WAYPOINT\t" + "1" * 70000 + "\n")
    with pytest.raises(wipdr.DataError, match=r"long.txt: line 2: longer than the limit"):
        wipdr.read_walk(bad)


def test_an_unknown_config_field_names_its_path(tmp_path):
    with pytest.raises(wipdr.ConfigError, match="r_wifii"):
        wipdr.evaluate([FIXTURE_FLOOR], ["ekf"], config={"schemes": {"ekf": {"scheme": "ekf", "r_wifii": 3.0}}})
    with pytest.raises(wipdr.ConfigError, match=r"matcher.k|k"):
        wipdr.evaluate([FIXTURE_FLOOR], ["ekf"], config={"matcher": {"k": 0}})
    missing = tmp_path / "none.toml"
    with pytest.raises(wipdr.DataError, match="none.toml"):
        wipdr.evaluate([FIXTURE_FLOOR], ["ekf"], config=missing)


def test_an_unknown_scheme_is_a_value_error():
    with pytest.raises(ValueError, match="nosuch"):
        wipdr.evaluate([FIXTURE_FLOOR], ["nosuch"])
    rm = small_map()
    with pytest.raises(ValueError, match="nosuch"):
        wipdr.Positioner(rm, "nosuch")


def test_too_few_walks_for_the_folds():
    floor = wipdr.read_floor(FIXTURE_FLOOR)
    small = wipdr.Floor(floor.walks[:3], plan=floor.plan)
    with pytest.raises(wipdr.InputError, match="3 walks, need at least 5"):
        wipdr.evaluate([small], ["ekf"])


def test_bad_arrays_are_input_errors():
    with pytest.raises(wipdr.InputError, match=r"expected shape \(n, 3\), got \(1, 2\)"):
        wipdr.Walk("w", [[0.0, 1.0]])
    with pytest.raises(wipdr.InputError, match=r"accelerometer\[1\]: must be finite"):
        wipdr.Walk("w", accelerometer=[[0, 0, 0, 9.8], [1, np.nan, 0, 9.8]])
    with pytest.raises(wipdr.InputError, match=r"waypoints\[0\]: time must be a whole number"):
        wipdr.Walk("w", [[0.5, 1.0, 2.0]])
    with pytest.raises(wipdr.InputError, match="unknown key"):
        wipdr.Walk("w", metadata={"modle": "x"})
    with pytest.raises(wipdr.InputError, match=r"scans\[0\] entries\[0\]"):
        wipdr.Walk("w", scans=[(0, [("zz:00", -50.0)])])
    with pytest.raises(wipdr.InputError, match="2 positions but 1 scans"):
        wipdr.RadioMap.from_records([[0.0, 0.0], [1.0, 0.0]], [[(1, -50.0)]])
    with pytest.raises(wipdr.InputError, match="matcher.k: 5 neighbours asked of a radio map of 1"):
        wipdr.RadioMap.from_records([[0.0, 0.0]], [[(1, -50.0)]])


def test_bad_samples_are_input_errors():
    p = wipdr.Positioner(small_map(), "ekf")
    with pytest.raises(wipdr.InputError, match="finite"):
        p.push_accelerometer(0, float("inf"), 0.0, 9.8)
    with pytest.raises(wipdr.InputError, match="BSSID"):
        p.push_scan(0, [(1 << 50, -50.0)])
    with pytest.raises(wipdr.InputError, match="rssi"):
        p.push_scan(0, [("00:00:00:00:00:01", "loud")])
    with pytest.raises(wipdr.InputError, match="time"):
        p.push_pressure(float("nan"), 1000.0)
    assert p.counts()["samples"] == 0
