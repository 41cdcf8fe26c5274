"""Bring your own terrain: a custom world through survey → costmap → `dgt plan`."""

import warnings

import numpy as np
import pytest

from dgt_lib.app.cli import main
from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.core.controller import MPPIConfig, with_controller
from dgt_lib.mapping.baselines import SlopeModel, slope_costmap
from dgt_lib.stages.costmaps import world_bev
from dgt_lib.world.worlds import from_heightmap

RES = 0.4


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    path = tmp_path_factory.mktemp("data")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(artifacts.DATA_ENV_VAR, str(path))
        yield path


def ramp_world() -> object:
    """A 60 m × 40 m world: flat, then a 15° ramp rising toward +x, then a plateau."""
    x = (np.arange(150) + 0.5) * RES
    h = np.clip((x - 15.0) * np.tan(np.radians(15.0)), 0.0, 6.0)
    return from_heightmap(np.tile(h, (100, 1)).astype(np.float32), RES, name="ramp")


def test_custom_ramp_costs_more_uphill_than_downhill_for_carla_cola(data_dir):
    world = ramp_world()
    bev, path = world_bev(world, get_profile("smoke"), progress=False)
    assert path.startswith("bev/custom/ramp_")
    cola = SlopeModel(theta0=0.0, theta_min=-0.6, theta_max=0.2, p_u=1.0, p_d=2.0)
    cost = slope_costmap(bev, [cola], 8, progress=False)[0]
    r, c = bev.grid.xy_to_cell(np.full(5, 30.0), np.linspace(15, 25, 5))  # mid-ramp
    uphill, downhill = cost[0][r, c].mean(), cost[4][r, c].mean()  # +x vs −x
    assert uphill > 0.9 and downhill < 0.5


def test_dgt_plan_on_a_tiny_custom_world_file(data_dir, tmp_path, capsys):
    heights = np.zeros((80, 120), np.float32)
    heights[30:50, 55:65] = 3.0  # a block to drive around
    np.save(tmp_path / "tiny.npy", heights)
    args = ["plan", "--world", str(tmp_path / "tiny.npy"), "--vehicle", "jeep",
            "--start", "8,16,0", "--goal", "40,16", "--method", "binary", "--profile", "smoke"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "found: length" in out and "figure:" in out
    assert list((data_dir / "smoke" / "seed-0" / "plans").glob("*.png"))


def _tiny_heights(pen: bool) -> np.ndarray:
    """The tiny 48 m × 32 m world: a 3 m block to drive around, or (``pen``) a 3 m wall
    2.4 m thick boxing in a 22.4 m × 20.8 m pen around (8, 16) m, the goal (40, 16) outside."""
    heights = np.zeros((80, 120), np.float32)
    if pen:
        heights[8:72, 2:70] = 3.0
        heights[14:66, 8:64] = 0.0
    else:
        heights[30:50, 55:65] = 3.0
    return heights


@pytest.mark.parametrize("pen,settings,status,failure,reason", [
    (True, ["planner.heuristic=euclidean"], 1, "no_path",
     "no path exists: every pose the search can reach was expanded (open list exhausted)"),
    (False, ["planner.max_expansions=1"], 3, "budget",
     "search budget exhausted after 1 expansions (planner.max_expansions=1): no path found "
     "yet, none ruled out; raise it, e.g. --set planner.max_expansions=2")],
    ids=["boxed-in", "budget"])
def test_dgt_plan_tells_no_path_from_an_exhausted_budget(data_dir, tmp_path, capsys, pen,
                                                         settings, status, failure, reason):
    """A start boxed in (the search empties its open list) exits 1 and says no path exists;
    a query with a path, searched with max_expansions=1, exits 3 and names the setting to
    raise: in the report and in ``--json``'s ``failure`` and ``reason``."""
    import json

    np.save(tmp_path / "tiny.npy", _tiny_heights(pen))
    args = ["plan", "--world", str(tmp_path / "tiny.npy"), "--vehicle", "jeep",
            "--start", "8,16,0", "--goal", "40,16", "--method", "binary", "--profile", "smoke"]
    for name in settings:
        args += ["--set", name]
    assert main(args) == status
    assert f"  not found: {reason} (" in capsys.readouterr().out
    assert main([*args, "--json"]) == status
    report = json.loads(capsys.readouterr().out)
    assert not report["found"] and report["path"] == [] and report["cost"] is None
    assert report["failure"] == failure and report["reason"] == reason


def test_dgt_plan_help_names_every_exit_status():
    """``dgt plan``'s exit statuses: one per kind of planner failure, all in its help."""
    import argparse

    from dgt_lib.app.cli import PLAN_EXIT, build_parser
    from dgt_lib.navigation.planner import FAILURES

    assert sorted(PLAN_EXIT) == sorted(FAILURES)
    assert sorted(PLAN_EXIT.values()) == [0, 1, 3]  # 2: an invalid query
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    text = " ".join(sub.choices["plan"].format_help().split())
    for said in ("0: a path was found", "1: no path exists", "2: an invalid query",
                 "3: the search budget ran out", "planner.max_expansions", "planner.max_time_s"):
        assert said in text, said


@pytest.mark.parametrize("start,message", [("500,16,0", "off the map"),
                                           ("24,16,0", "in an obstacle")])
def test_dgt_plan_bad_start_is_a_clear_error(data_dir, tmp_path, capsys, start, message):
    heights = np.zeros((80, 120), np.float32)
    heights[30:50, 55:65] = 3.0
    np.save(tmp_path / "tiny.npy", heights)
    assert main(["plan", "--world", str(tmp_path / "tiny.npy"), "--vehicle", "jeep",
                 "--start", start, "--goal", "40,16", "--method", "binary",
                 "--profile", "smoke"]) == 2
    assert message in capsys.readouterr().err


def test_dgt_plan_rejects_unknown_world_and_bad_numbers(data_dir, capsys):
    assert main(["plan", "--world", "nowhere.npy", "--vehicle", "jeep", "--start", "1,2,0",
                 "--goal", "3,4", "--profile", "smoke"]) == 2
    assert "neither a world" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["plan", "--world", "hill", "--vehicle", "jeep", "--start", "1,2",
              "--goal", "3,4"])


def test_a_mostly_unobserved_map_warns_why_and_the_error_says_unobserved(data_dir, tmp_path,
                                                                         capsys):
    """Heights in centimetres (600 m of relief): most of the map is below the survey's
    depth reach. The user must hear why, not just that the start is 'in an obstacle'."""
    x = (np.arange(150) + 0.5) * RES
    ramp_cm = np.clip((x - 15.0) * np.tan(np.radians(15.0)), 0.0, 6.0) * 100.0
    np.save(tmp_path / "ramp_cm.npy", np.tile(ramp_cm, (100, 1)))
    with pytest.warns(UserWarning, match="unobserved in its BEV map") as caught:
        assert main(["plan", "--world", str(tmp_path / "ramp_cm.npy"), "--vehicle", "jeep",
                     "--start", "5,20,0", "--goal", "55,20", "--method", "binary",
                     "--profile", "smoke"]) == 2
    assert "heights span 0.0 to 600.0 m" in str(caught[0].message)
    err = capsys.readouterr().err
    assert "in an obstacle" in err and "hits unobserved cells" in err


def test_a_well_observed_custom_map_does_not_warn(data_dir):
    from dgt_lib.stages.collect import UnobservedMapWarning

    with warnings.catch_warnings():
        warnings.simplefilter("error", UnobservedMapWarning)
        world_bev(ramp_world(), get_profile("smoke"), progress=False)


def tiny_world():
    """48 m × 32 m of flat ground with a 3 m block (x 22–26 m, y 12–20 m) and one tree."""
    heights = np.zeros((80, 120), np.float32)
    heights[30:50, 55:65] = 3.0
    return from_heightmap(heights, RES, trees=[(40.0, 26.0, 0.3, 6.0)], name="tiny")


def _no_artifacts(*args, **kwargs):
    raise AssertionError("no artifact may be built before the query is checked")


HILL_TREE = "18.38,127.67"  # the hill world's first tree (smoke profile)


@pytest.mark.parametrize("start,goal,message", [
    ("500,14,0", "30,96", "start (500.00, 14.00) m is off the map"),
    (f"{HILL_TREE},0", "30,96", "is on a tree: the carla_cola's"),
    ("30,14,0.8", HILL_TREE, "goal (18.38, 127.67) m is inside the tree trunk"),
    ("0.5,70,0", "30,96", "too close to the map edge"),
])
def test_a_start_or_goal_bad_on_the_world_alone_fails_before_any_work(
        tmp_path, monkeypatch, capsys, start, goal, message):
    """On an empty data directory an off-map start used to be reported after collecting,
    training and mapping (58 s in smoke, hours in paper)."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    monkeypatch.setattr(artifacts, "ensure", _no_artifacts)
    assert main(["plan", "--world", "hill", "--vehicle", "carla_cola", "--start", start,
                 "--goal", goal, "--method", "dgt", "--profile", "smoke"]) == 2
    out, err = capsys.readouterr()
    assert message in err and "training" not in out
    assert list(tmp_path.iterdir()) == []  # nothing collected, trained or written


def test_a_start_on_steep_ground_fails_before_the_dataset_and_model(data_dir, monkeypatch,
                                                                     capsys):
    """Steepness needs the occupancy map (‖∇H̄‖ > τ_s): it is checked on the BEV maps alone,
    before collection and training, with the planner's own rule."""
    import dgt_lib.stages.costmaps as costmaps
    from dgt_lib.app.plan_one import plan_query
    from dgt_lib.navigation.planner import InvalidQueryError

    monkeypatch.setattr(costmaps, "ensure_dataset", _no_artifacts)
    with pytest.raises(InvalidQueryError, match="in an obstacle: .* hits occupied cells"):
        plan_query(tiny_world(), "jeep", (24.0, 16.0, 0.0), (40.0, 16.0), method="dgt",
                   profile="smoke", progress=False)
    assert "training" not in capsys.readouterr().out


def test_negative_coordinates_parse_on_the_command_line(tmp_path, monkeypatch, capsys):
    """`--start -5,14,0.8` was an argparse error ("expected one argument")."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    assert main(["plan", "--world", "hill", "--vehicle", "jeep", "--start", "-5,14,0.8",
                 "--goal", "-3.5,-4", "--profile", "smoke"]) == 2
    assert "start (-5.00, 14.00) m is off the map" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # still a number list, or an error naming the format
        main(["plan", "--world", "hill", "--vehicle", "jeep", "--start", "-5,nan,0",
              "--goal", "3,4"])
    assert "--start must be x,y,yaw: finite numbers" in capsys.readouterr().err


def test_a_goal_within_the_tolerance_plans_and_drives_a_zero_length_path(data_dir):
    """--drive with a goal 0.5 m away failed: "path needs at least two distinct points"."""
    from dgt_lib.app.plan_one import plan_query

    report = plan_query(tiny_world(), "jeep", (8.0, 16.0, 0.0), (8.5, 16.0), method="binary",
                        profile="smoke", drive=True, progress=False)
    assert report.plan.success and report.plan.length_m == 0.0
    assert report.outcome.success and report.outcome.duration_s == 0.0
    assert "already within the goal tolerance" in report.summary()


def test_distinct_queries_write_distinct_files(data_dir):
    """Files were named by rounded x, y only: another heading, a start 0.3 m away or
    another terrain of the same name overwrote the previous query's figure and recording."""
    from dgt_lib.app.plan_one import plan_query

    world = tiny_world()
    starts = [(8.0, 16.0, 0.0), (8.0, 16.0, np.pi / 2), (8.3, 16.2, 0.0)]
    figures = set()
    for start in starts:
        report = plan_query(world, "jeep", start, (40.0, 16.0), method="binary",
                            profile="smoke", progress=False)
        assert report.figure.exists() and report.recording.exists()
        figures.add(report.figure)
    assert len(figures) == 3
    other = from_heightmap(world.heights + 0.1, RES, trees=world.trees, name="tiny")
    again = plan_query(other, "jeep", starts[0], (40.0, 16.0), method="binary",
                       profile="smoke", progress=False)
    assert again.figure not in figures  # same name, other terrain
    same = plan_query(world, "jeep", starts[0], (40.0, 16.0), method="binary",
                      profile="smoke", progress=False)
    assert same.figure in figures  # the same query replaces its own files


def test_the_training_notice_says_which_stages_run_and_promises_no_time(tmp_path,
                                                                         monkeypatch):
    """`dgt plan` said demo training takes "about 40 minutes", whatever the machine: it
    now says what will run before the costmap, and no duration."""
    import re

    from dgt_lib.app.query import training_notice
    from dgt_lib.stages.paths import data_dir
    from dgt_lib.stages.train import model_relpath

    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    demo = get_profile("demo")
    notice = training_notice("dgt", "carla_cola", demo)
    assert notice.startswith("No trained multitask model for profile 'demo' yet: collecting "
                             "the training world's 130 driving episodes (those not cached "
                             "yet), building the dataset, then training it.")
    assert not re.search(r"minute|hour|second|about|a few|a while", notice)
    assert "No slope-based fit" in training_notice("slope", "jeep", demo)
    assert "trained single:jeep model" in training_notice("single-task", "jeep", demo)
    assert training_notice("binary", "jeep", demo) is None
    data_dir(demo).mkdir(parents=True)
    (data_dir(demo) / "dataset.npz").write_bytes(b"")
    assert training_notice("isotropic", "jeep", demo).endswith(
        "yet: training it on the cached dataset. Later queries reuse it.")
    (data_dir(demo) / model_relpath("multitask")).parent.mkdir(parents=True)
    (data_dir(demo) / model_relpath("multitask")).write_bytes(b"")
    assert training_notice("dgt", "jeep", demo) is None


def test_plan_json_is_the_only_thing_on_stdout_and_has_the_path_and_the_drive(data_dir,
                                                                               tmp_path):
    """`dgt plan --json` for scripts: one JSON object on stdout — the path's rows x, y, yaw,
    its length and cost, the drive's outcome — and the progress on stderr, even what worker
    processes and the simulator write."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    heights = np.zeros((80, 120), np.float32)
    heights[30:50, 55:65] = 3.0
    np.save(tmp_path / "tiny.npy", heights)
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run(
        [sys.executable, "-m", "dgt_lib", "plan", "--world", str(tmp_path / "tiny.npy"),
         "--vehicle", "jeep", "--start", "8,16,0", "--goal", "20,16", "--method", "binary",
         "--profile", "smoke", "--drive", "--json"],
        capture_output=True, text=True, cwd=root, timeout=600,
        env={**os.environ, "PYTHONPATH": str(root)})
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)  # the whole of stdout
    assert report["found"] and report["reason"] is None
    path = np.array(report["path"])
    assert path.shape[1] == 3 and len(path) >= 2
    np.testing.assert_allclose(path[0], [8.0, 16.0, 0.0], atol=1e-6)
    assert np.hypot(*(path[-1, :2] - [20.0, 16.0])) <= 1.0  # within the goal tolerance
    assert report["length_m"] == pytest.approx(
        np.hypot(*np.diff(path[:, :2], axis=0).T).sum(), rel=0.05)
    assert report["cost"] > 0 and report["route"] is None  # a custom world has no routes
    assert report["outcome"]["success"] and report["outcome"]["reason"] == "success"
    assert Path(report["figure"]).exists()
    assert "found: length" not in done.stdout


def test_a_world_with_named_routes_reports_the_route_taken(data_dir):
    """On the hill the plan's route (A or B) is what Experiment 1 is about: `dgt plan`
    names it (here a small world laid out like the hill, its Route A south of the block,
    Route B north of it)."""
    from dataclasses import replace

    from dgt_lib.app.plan_one import plan_query

    south = np.array([[8.0, 8.0], [34.0, 8.0]])
    north = np.array([[8.0, 25.0], [34.0, 25.0]])
    world = replace(tiny_world(), name="hill", routes={"A": south, "B": north})
    report = plan_query(world, "jeep", (8.0, 8.0, 0.0), (34.0, 8.0), method="binary",
                        profile="smoke", progress=False)
    assert report.route == "A" and report.as_dict()["route"] == "A"
    assert "route: A" in report.summary()
    report = plan_query(world, "jeep", (8.0, 25.0, 0.0), (34.0, 25.0), method="binary",
                        profile="smoke", progress=False)
    assert report.route == "B"
    assert plan_query(tiny_world(), "jeep", (8.0, 25.0, 0.0), (34.0, 25.0), method="binary",
                      profile="smoke", progress=False).route is None


def test_dgt_plan_under_other_settings_writes_other_files(data_dir, tmp_path, capsys):
    """``--set planner.beta=0`` plans another path: its figure and recording must not
    overwrite the default settings' (and the default query keeps its file name)."""
    heights = np.zeros((80, 120), np.float32)
    heights[30:50, 55:65] = 3.0
    np.save(tmp_path / "betas.npy", heights)
    args = ["plan", "--world", str(tmp_path / "betas.npy"), "--vehicle", "jeep",
            "--start", "8,16,0", "--goal", "40,16", "--method", "binary", "--profile", "smoke"]
    plans = data_dir / "smoke" / "seed-0" / "plans"
    assert main(args) == 0
    assert main([*args, "--set", "planner.beta=0"]) == 0
    assert main([*args, "--set", "planner.beta=150"]) == 0  # the profile's own value
    capsys.readouterr()
    rrds = {p.stem for p in plans.glob("betas_*.rrd")}
    stems = {p.stem for p in plans.glob("betas_*.png")}
    assert len(stems) == 2 and stems <= rrds
    tagged = [s for s in stems if "_set-" in s]
    assert len(tagged) == 1 and tagged[0].split("_set-")[0] in stems


def test_output_stem_of_the_profile_s_own_settings_is_unchanged():
    from dgt_lib.app.query import output_stem
    from dgt_lib.core.vehicles import get_vehicle

    world, jeep = ramp_world(), get_vehicle("jeep")
    smoke = get_profile("smoke")
    stem = output_stem(world, jeep, "dgt", (1.0, 2.0, 0.0), (30.0, 2.0))
    assert stem == "ramp_jeep_dgt_1.0_2.0_0deg_to_30.0_2.0_c57fbca1"  # the stored plans' name
    assert output_stem(world, jeep, "dgt", (1.0, 2.0, 0.0), (30.0, 2.0), profile=smoke) == stem
    same = smoke.with_overrides({"planner.beta": 150, "seeds": 2})  # nothing the plan reads
    assert output_stem(world, jeep, "dgt", (1.0, 2.0, 0.0), (30.0, 2.0), profile=same) == stem
    other = smoke.with_overrides({"planner.beta": 0})
    tagged = output_stem(world, jeep, "dgt", (1.0, 2.0, 0.0), (30.0, 2.0), profile=other)
    assert tagged.startswith(stem + "_set-") and len(tagged) == len(stem) + 13


@pytest.mark.parametrize("controller", ["paper", "robust", "terrain"])
def test_dgt_plan_drive_drives_the_profile_s_controller_and_seed(data_dir, monkeypatch,
                                                                 controller):
    """--drive always drove the paper's MPPI with seed 0 whatever experiments.controller
    said; now it drives what a trial would: the controller's settings, the profile's seed,
    and for the terrain critic the costmap the plan was made on."""
    from dgt_lib.app.plan_one import plan_query
    from dgt_lib.navigation import drive as drive_module

    seen = {}

    def fake_drive(world, vehicle, path, goal, **kwargs):
        seen.update(kwargs)
        raise RuntimeError("stop here")

    monkeypatch.setattr(drive_module, "drive", fake_drive)
    profile = get_profile("smoke").with_overrides({"experiments.controller": controller,
                                                   "seed": 5})
    with pytest.raises(RuntimeError, match="stop here"):
        plan_query(tiny_world(), "jeep", (8.0, 16.0, 0.0), (40.0, 16.0), method="binary",
                   profile=profile, drive=True, progress=False)
    assert seen["seed"] == 5
    assert seen["mppi"] == profile.mppi and profile.mppi.batch_size == 256  # smoke's samples
    assert profile.mppi == with_controller(get_profile("smoke").mppi, controller)
    if controller == "terrain":
        assert seen["costmap"].ndim == 3 and seen["costmap"].shape[1:] == (80, 120)
    else:
        assert "costmap" not in seen


def test_robust_and_paper_controllers_give_different_first_commands_at_a_full_lock_start():
    """The first command on a plan that turns at full lock at once: the paper's MPPI and
    the robust one (biased samples, half the yaw-rate noise) answer differently, so the
    controller --drive is handed is the one it drives."""
    from dgt_lib.core.vehicles import get_vehicle
    from dgt_lib.navigation.drive import drive

    radius = get_vehicle("jeep").min_turn_radius_m
    theta = np.linspace(0.0, np.pi, 40)  # a half circle: its end 7 m away
    path = np.column_stack([20.0 + radius * np.sin(theta), 10.0 + radius * (1 - np.cos(theta)),
                            theta])
    first = {}
    for name in ("paper", "robust"):
        commands = []
        drive(tiny_world(), "jeep", path, path[-1, :2], time_limit_s=0.5, seed=0,
              mppi=with_controller(MPPIConfig(batch_size=256), name),
              on_command=lambda state, v, steer, out=commands: out.append((v, steer)))
        first[name] = commands[0]
    assert first["paper"] != first["robust"]


def test_a_long_vehicle_or_world_name_gives_a_file_name_that_fits(data_dir):
    """A 210-character vehicle name lost the computed plan when its figure was saved."""
    from dataclasses import replace

    from dgt_lib.app.query import output_stem
    from dgt_lib.core.vehicles import get_vehicle

    world = from_heightmap(np.zeros((40, 40), np.float32), RES, name="w" * 300)
    stems = {output_stem(world, replace(get_vehicle("jeep"), name="v" * 209 + end), "dgt",
                         (1, 2, 0), (3, 4)) for end in "ab"}
    assert len(stems) == 2  # names that share their start stay apart
    assert all(len(s.encode()) + len(".png.lock") < 255 for s in stems)
