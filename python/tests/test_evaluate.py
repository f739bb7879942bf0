"""`wipdr.evaluate` returns exactly the document `wipdr eval --json` writes."""

import pytest

import wipdr
from conftest import DATA, FIXTURE_FLOOR, assert_close, cli_eval_json

SCHEMES = ["wifi", "pdr", "ekf", "pmf"]


def test_evaluate_equals_cli_json_on_the_fixtures(wipdr_bin, tmp_path):
    cli = cli_eval_json(wipdr_bin, tmp_path, [FIXTURE_FLOOR], SCHEMES)
    py = wipdr.evaluate([str(FIXTURE_FLOOR)], SCHEMES)
    assert py.keys() == {
        "pooled", "floors", "walks", "schemes", "mode", "config", "skips", "skipped_runs", "motion",
        "scan_likelihood",
    }
    assert py["mode"] == "causal"
    assert py["schemes"] == SCHEMES
    assert list(py["floors"]) == ["sim/F1"]
    assert len(py["walks"]) == 10 * len(SCHEMES)
    assert all(py["pooled"][s]["count"] > 0 for s in SCHEMES)
    assert_close(py, cli)


def test_offline_evaluate_equals_cli_offline(wipdr_bin, tmp_path):
    out = tmp_path / "offline.json"
    from conftest import run_cli
    import json
    run_cli(wipdr_bin, "eval", "--data", FIXTURE_FLOOR, "--schemes", "wifi,ekf", "--offline", "--json", out)
    py = wipdr.evaluate([str(FIXTURE_FLOOR)], ["wifi", "ekf"], offline=True)
    assert py["mode"] == "offline"
    assert_close(py, json.loads(out.read_text()))


def test_evaluate_with_a_config_equals_cli(wipdr_bin, tmp_path):
    config = tmp_path / "c.toml"
    config.write_text("map_matching = true\n[matcher]\nk = 3\n")
    cli = cli_eval_json(wipdr_bin, tmp_path, [FIXTURE_FLOOR], ["ekf"], config=config)
    from_file = wipdr.evaluate([FIXTURE_FLOOR], ["ekf"], config=config)
    from_dict = wipdr.evaluate([FIXTURE_FLOOR], ["ekf"], config={"map_matching": True, "matcher": {"k": 3}})
    assert from_file["config"]["matcher"]["k"] == 3
    assert_close(from_file, cli)
    assert_close(from_dict, cli)
    default = wipdr.evaluate([FIXTURE_FLOOR], ["ekf"])
    assert default["pooled"]["ekf"]["mean"] != from_file["pooled"]["ekf"]["mean"]


def test_a_floor_object_evaluates_as_its_folder():
    floor = wipdr.read_floor(FIXTURE_FLOOR)
    assert floor.name == "sim/F1"
    assert_close(wipdr.evaluate([floor], ["ekf"]), wipdr.evaluate([FIXTURE_FLOOR], ["ekf"]))


def test_a_floor_built_from_arrays_evaluates_as_the_one_read():
    read = wipdr.read_floor(FIXTURE_FLOOR)
    rebuilt = []
    for w in read.walks:
        rebuilt.append(
            wipdr.Walk(
                w.id,
                w.waypoints,
                accelerometer=w.accelerometer,
                gyroscope=w.gyroscope,
                magnetometer=w.magnetometer,
                rotation_vector=w.rotation_vector,
                pressure=w.pressure,
                scans=w.scans_with_times,
                waypoint_floors=w.waypoint_floors,
                metadata=w.metadata,
            )
        )
    plan = read.plan
    floor = wipdr.Floor(rebuilt, plan=wipdr.FloorPlan(plan.width, plan.height, outline=plan.outline), name="sim/F1")
    # The fixture plan has units (shops); their walls are not rebuilt here, so compare a
    # scheme that does not use walls or walkable space, under the papers' settings (the
    # defaults' map matching and path-loss extension use walkable space).
    paper = {"preset": "paper"}
    assert_close(
        wipdr.evaluate([floor], ["ekf"], config=paper),
        wipdr.evaluate([read], ["ekf"], config=paper),
    )


@pytest.mark.skipif(not (DATA / "ilc20" / "site1" / "F1").is_dir(), reason=f"real data not found under {DATA} (set WIPDR_DATA to the data root)")
def test_evaluate_equals_cli_json_on_a_real_floor(wipdr_bin, tmp_path):
    floor = DATA / "ilc20" / "site1" / "F1"
    cli = cli_eval_json(wipdr_bin, tmp_path, [floor], ["wifi", "ekf"])
    py = wipdr.evaluate([wipdr.read_floor(floor)], ["wifi", "ekf"])
    assert_close(py["pooled"], cli["pooled"])
    assert py["pooled"]["ekf"]["count"] > 500  # 626 waypoints of site1/F1 are scored
    assert_close(py, cli)
