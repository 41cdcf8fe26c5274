"""Closed-loop trials: routes, queries, the trial runner's error handling, and tables."""

import importlib.util
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.core.controller import MPPIConfig
from dgt_lib.evaluation import trials
from dgt_lib.evaluation.experiments import ExperimentResult, run_experiment
from dgt_lib.evaluation.journal import Journal, read_journal
from dgt_lib.evaluation.paper import PAPER
from dgt_lib.evaluation.queries import Query, classify_route, hill_queries, ridge_queries
from dgt_lib.evaluation.trials import (
    TrialResult,
    TrialTask,
    run_trial,
    run_trials,
    trial_tasks,
)
from dgt_lib.navigation.control.mppi import MPPIController
from dgt_lib.navigation.drive import MPPI_DT_S, drive
from dgt_lib.navigation.outcome import TrialOutcome
from dgt_lib.stages.experiments import (
    experiment_path,
    experiment_stem,
    reproduce_command,
    stored_experiment,
    trial_maps,
)
from dgt_lib.world.terrain import get_world
from dgt_lib.world.worlds import from_heightmap

PROFILE = get_profile("smoke")
FEW = MPPIConfig(batch_size=128)  # the paper's MPPI with fewer samples: fast trials


def test_routes_are_recognised_on_the_hill_and_the_ridge():
    hill, ridge = get_world("hill", PROFILE), get_world("ridge", PROFILE)
    assert classify_route(hill, hill.routes["A"]) == "A"
    assert classify_route(hill, hill.routes["B"][::-1]) == "B"  # direction does not matter
    assert classify_route(ridge, ridge.routes["A"]) == "smooth"
    assert classify_route(ridge, ridge.routes["B"]) == "sharp"
    straight_north = np.column_stack([np.full(30, 50.0), np.linspace(15, 65, 30)])
    assert classify_route(ridge, straight_north) == "sharp"  # the ridge is sharp at x = 50
    straight_east = np.column_stack([np.linspace(10, 130, 50), np.full(50, 130.0)])
    assert classify_route(hill, straight_east) == "other"
    assert classify_route(get_world("eval", PROFILE), straight_east) == ""


def test_queries_alternate_directions_and_are_seeded():
    hill = get_world("hill", PROFILE)
    cfg = PROFILE.experiments
    q = hill_queries(hill, 4, cfg, seed=3)
    assert [x.label for x in q] == ["ascent", "descent", "ascent", "descent"]
    base, summit = np.array(hill.landmarks["base"]), np.array(hill.landmarks["summit"])
    assert np.abs(np.array(q[0].start[:2]) - base).max() <= cfg.start_jitter_m
    assert np.abs(np.array(q[0].goal) - summit).max() <= cfg.start_jitter_m
    assert q == hill_queries(hill, 4, cfg, seed=3) and q != hill_queries(hill, 4, cfg, seed=4)
    r = ridge_queries(get_world("ridge", PROFILE), 2, cfg, seed=0)
    assert r[0].start[1] < r[0].goal[1] and r[1].start[1] > r[1].goal[1]


def test_a_short_closed_loop_trial_succeeds_on_flat_ground():
    world = from_heightmap(np.zeros((100, 200), np.float32), 0.4, name="flat")
    path = np.column_stack([np.linspace(10, 60, 126), np.full(126, 20.0), np.zeros(126)])
    outcome, traj, speed = drive(world, "jeep", path, (60.0, 20.0), time_limit_s=30.0,
                                 mppi=FEW)
    assert outcome.success and outcome.reason == "success"
    assert np.hypot(*(traj[-1, 1:3] - [60.0, 20.0])) < 5.0
    assert speed.max() > 3.0  # it drove, at close to the commanded 5 m/s
    assert np.abs(traj[:, 2] - 20.0).max() < 1.0  # and stayed on the line


def test_a_vehicle_started_beside_its_plan_rejoins_it_and_arrives():
    # studies/off_plan.py's disturbance: at rest 2.5 m left of the path, MPPI steers back
    world = from_heightmap(np.zeros((100, 200), np.float32), 0.4, name="flat")
    path = np.column_stack([np.linspace(10, 60, 126), np.full(126, 20.0), np.zeros(126)])
    outcome, traj, _ = drive(world, "jeep", path, (60.0, 20.0), time_limit_s=30.0,
                             mppi=FEW, start_pose=(10.0, 22.5, 0.0))
    assert abs(traj[0, 2] - 22.5) < 0.3  # it started where it was put, not on the path
    assert outcome.success
    assert abs(traj[-1, 2] - 20.0) < 1.0  # back on the line by the goal


def _study(name: str, monkeypatch):
    """``studies/<name>.py`` loaded as a module (with ``studies/`` on the path, as when the
    script runs: it imports ``runner``)."""
    studies = Path(__file__).resolve().parent.parent / "studies"
    monkeypatch.syspath_prepend(str(studies))
    spec = importlib.util.spec_from_file_location(name, studies / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_off_plan_reports_the_terrain_under_a_start_and_leaves_out_starts_across_a_bank(
        monkeypatch):
    # studies/off_plan.py's failure list: on a plane rising 0.2 m per m to the east, a start
    # facing east is on a +11.3° grade, one facing north has its left (west) side low
    off_plan = _study("off_plan", monkeypatch)
    x = np.arange(200) * 0.4
    world = from_heightmap(np.tile(0.2 * x, (100, 1)).astype(np.float32), 0.4, name="tilted")
    x0, x1, y0, y1 = world.extent
    centre = ((x0 + x1) / 2, (y0 + y1) / 2)
    grade, cross = off_plan.start_grades_deg(world, np.array([*centre, 0.0]))
    assert grade == pytest.approx(11.31, abs=0.05) and cross == pytest.approx(0.0, abs=0.05)
    grade, cross = off_plan.start_grades_deg(world, np.array([*centre, np.pi / 2]))
    assert grade == pytest.approx(0.0, abs=0.05) and cross == pytest.approx(-11.31, abs=0.05)
    # a 1 m bank across the plane: carla_cola cannot be put at rest across it, beside it can
    bank = np.tile(np.where(x < 40.0, 0.0, 1.0), (100, 1)).astype(np.float32)
    banked = from_heightmap(bank, 0.4, name="bank")
    assert not off_plan.can_stand(banked, "carla_cola", np.array([40.0, centre[1], np.pi / 2]))
    assert off_plan.can_stand(banked, "carla_cola", np.array([46.0, centre[1], np.pi / 2]))
    assert off_plan.can_stand(world, "carla_cola", np.array([*centre, 0.0]))  # 11° is no bank


def test_watching_a_trials_commands_does_not_change_the_trial():
    """`studies/replay_trial.py` prints every command MPPI gives through `on_command`:
    one per ~50 ms control period, the speed command and the steering within the
    vehicle's lock (−1 … 1), and the trial driven the same to the bit as without watching."""
    world = from_heightmap(np.zeros((200, 200), np.float32), 0.4, name="flat")  # 80 m × 80 m
    t = np.linspace(0.0, np.pi / 2, 60)  # a quarter circle of 20 m radius, then straight
    arc = np.column_stack([10 + 20 * np.sin(t), 40 - 20 * np.cos(t), t])
    path = np.vstack([arc, np.column_stack([np.full(40, 30.0), np.linspace(41, 70, 40),
                                            np.full(40, np.pi / 2)])])
    kwargs = {"time_limit_s": 30.0, "mppi": FEW, "seed": 5}
    seen = []
    watched = drive(world, "jeep", path, (30.0, 70.0),
                    on_command=lambda s, v, steer: seen.append((s.time_s, v, steer)), **kwargs)
    plain = drive(world, "jeep", path, (30.0, 70.0), **kwargs)
    np.testing.assert_array_equal(watched[1], plain[1])
    assert watched[0] == plain[0] and plain[0].success
    times = np.array([s[0] for s in seen])
    period = np.diff(times)  # MPPI_DT_S in whole physics steps (6 × 8 ms)
    np.testing.assert_allclose(period, period[0], atol=1e-9)
    assert abs(period[0] - MPPI_DT_S) < 0.005
    assert times[-1] <= plain[0].duration_s
    steer = np.array([s[2] for s in seen])
    assert np.abs(steer).max() <= 1.0
    assert steer[:20].mean() > 0.05  # the left turn is steered left (positive)


def test_watching_mppis_sampled_costs_does_not_change_the_trial(monkeypatch):
    """`studies/replay_trial.py --critics` reports, per MPPI call, how many sampled
    sequences collide: beside a wall some do, the shares are percentages, the cheapest
    sequence's speed is within the controller's range, the trial is driven the same to the
    bit as without watching, and the controller is itself again afterwards."""
    replay = _study("replay_trial", monkeypatch)
    world = from_heightmap(np.zeros((100, 200), np.float32), 0.4, name="flat")  # 80 m × 40 m
    occupancy = np.zeros(world.grid.shape, np.uint8)
    rows = slice(*(int((y - world.grid.origin_xy[1]) / 0.4) for y in (22.0, 25.0)))
    cols = slice(*(int((x - world.grid.origin_xy[0]) / 0.4) for x in (25.0, 45.0)))
    occupancy[rows, cols] = 1  # a wall 2 m beside the path
    path = np.column_stack([np.linspace(10, 60, 126), np.full(126, 20.0), np.zeros(126)])
    kwargs = {"occupancy": occupancy, "grid": world.grid, "time_limit_s": 30.0,
              "mppi": FEW, "seed": 3}
    original = MPPIController._sampled_costs_compiled
    reports = []
    with replay.watching_sampled_costs(1.5) as latest:
        watched = drive(world, "jeep", path, (60.0, 20.0),
                        on_command=lambda s, v, steer: reports.append(latest()), **kwargs)
    assert MPPIController._sampled_costs_compiled is original
    plain = drive(world, "jeep", path, (60.0, 20.0), **kwargs)
    np.testing.assert_array_equal(watched[1], plain[1])
    assert watched[0] == plain[0]
    numbers = np.array([[float(x) for x in r] for r in reports])  # the table's cells
    hit, fast_hit, best_v = numbers[:, 0], numbers[:, 1], numbers[:, 2]
    assert ((0 <= hit) & (hit <= 100)).all() and hit.max() > 0  # near the wall some collide
    assert np.nanmax(fast_hit) <= 100
    assert ((0 <= best_v) & (best_v <= MPPIConfig().v_max)).all()


def test_a_drive_takes_other_mppi_settings_for_itself_only():
    """`studies/controller_variants.py` drives recorded plans with other MPPI settings:
    a lower target speed is driven slower, the next drive without it at 5 m/s again."""
    world = from_heightmap(np.zeros((100, 200), np.float32), 0.4, name="flat")
    path = np.column_stack([np.linspace(10, 60, 126), np.full(126, 20.0), np.zeros(126)])
    slow = drive(world, "jeep", path, (60.0, 20.0), time_limit_s=40.0,
                 mppi=replace(FEW, target_speed=2.5))
    again = drive(world, "jeep", path, (60.0, 20.0), time_limit_s=40.0, mppi=FEW)
    assert slow[0].success and again[0].success
    assert slow[2].max() < 3.2 < 4.0 < again[2].max()


def test_a_crashing_trial_is_recorded_as_an_error_not_raised():
    task = TrialTask("x", "no_such_world", "binary", "jeep", Query((0, 0, 0), (1, 1)), 0,
                     PROFILE, 0)
    result = run_trial(task, trial_maps)
    assert result.outcome.reason == "error" and not result.outcome.success
    assert "no_such_world" in result.outcome.detail  # the traceback is kept


def _result(method, label, ok, vehicle="carla_cola", route="A"):
    task = TrialTask("experiment1", "hill", method, vehicle, Query((0, 0, 0), (1, 1), label), 0,
                     PROFILE, 0)
    outcome = TrialOutcome(True, "success", 1.0) if ok else TrialOutcome.failure("immobilized")
    return TrialResult(task, outcome, route=route)


def test_tables_count_successes_and_put_the_paper_beside_ours():
    res = ExperimentResult("experiment1", "hill", [
        _result("dgt", "ascent", True), _result("dgt", "descent", True, route="B"),
        _result("binary", "ascent", False, route="B"), _result("binary", "descent", True,
                                                               route="B")])
    assert res.counts() == {"dgt": (2, 2), "binary": (1, 2)}
    table = res.table("carla_cola", PAPER["experiment1"]["carla_cola"])
    assert "| DGT-Map | 2 / 2 | 100.0 |" in table and "| 16 | 80.0 |" in table
    assert res.routes()[("dgt", "ascent")] == {"A": 1}
    assert "| Binary | 1 | 1 |" in res.reason_markdown()


@pytest.mark.parametrize("name", ["experiment9"])
def test_unknown_experiment_is_a_clear_error(name):
    with pytest.raises(ValueError, match="experiment1, experiment2"):
        run_experiment(name, PROFILE, load_maps=trial_maps)


def test_an_interrupted_run_resumes_from_its_journal(tmp_path, monkeypatch):
    from concurrent.futures import ThreadPoolExecutor

    tasks = [TrialTask("experiment1", "hill", m, "carla_cola", Query((i, 0, 0), (9, 9)), i,
                       PROFILE, i) for i in range(3) for m in ("dgt", "binary")]
    ran, stop = [], [True]

    def fake_trial(task, load_maps):
        ran.append(task)
        if task.index == 2 and task.method == "binary" and stop.pop():
            raise KeyboardInterrupt  # the user stops the run during the last trial
        ok = task.method == "dgt"
        return TrialResult(task, TrialOutcome(True, "success", 1.0) if ok
                           else TrialOutcome.failure("immobilized", 10.0))

    monkeypatch.setattr(trials, "run_trial", fake_trial)
    journal = tmp_path / "exp.trials.pkl"
    with ThreadPoolExecutor(1) as pool, pytest.raises(KeyboardInterrupt):
        run_trials(tasks, trial_maps, pool, progress=False, journal=journal)
    assert len(read_journal(journal)) == 5  # every finished trial was kept
    ran.clear()
    stop.append(False)
    with ThreadPoolExecutor(1) as pool:
        results = run_trials(tasks, trial_maps, pool, progress=False, journal=journal)
    assert ran == [tasks[-1]]  # only the unfinished trial runs again
    assert [r.task for r in results] == tasks  # task order, journaled ones included
    assert [r.outcome.success for r in results] == [True, False] * 3


def _journal_task(i):
    return TrialTask("x", "hill", "dgt", "jeep", Query((i, 0, 0), (9, 9)), i, PROFILE, i)


def _journaled(i):
    return TrialResult(_journal_task(i), TrialOutcome(True, "success", 1.0),
                       path=np.full((40, 2), float(i)))


def _damaged_journal(path, damage):
    """Five trials journaled; the third damaged: cut short by a crash with the last two
    appended after it (as a resumed run of the previous code did), or a byte of it
    changed on disk."""
    ends = [0]
    with Journal(path) as log:
        for i in range(5):
            log.append(_journaled(i))
            ends.append(path.stat().st_size)
    if damage == "crash":
        data = path.read_bytes()
        path.write_bytes(data[:ends[3] - 9] + data[ends[3]:])
    else:
        data = bytearray(path.read_bytes())
        data[(ends[2] + ends[3]) // 2] ^= 0xFF
        path.write_bytes(bytes(data))


@pytest.mark.parametrize("damage", ["crash", "corrupt"])
def test_a_damaged_journal_record_is_skipped_and_the_records_after_it_are_kept(
        tmp_path, damage):
    path = tmp_path / "j.pkl"
    _damaged_journal(path, damage)
    with pytest.warns(UserWarning, match="skipped 1 damaged record"):
        done = read_journal(path)
        assert list(done) == [_journal_task(i) for i in (0, 1, 3, 4)]
    np.testing.assert_array_equal(done[_journal_task(4)].path, np.full((40, 2), 4.0))
    assert read_journal(tmp_path / "missing.pkl") == {}


def test_a_resumed_run_redoes_only_the_damaged_trial(tmp_path, monkeypatch):
    from concurrent.futures import ThreadPoolExecutor

    path = tmp_path / "j.pkl"
    _damaged_journal(path, "crash")
    ran = []
    monkeypatch.setattr(trials, "run_trial",
                        lambda task, load_maps: ran.append(task.index) or _journaled(task.index))
    tasks = [_journal_task(i) for i in range(5)]
    with ThreadPoolExecutor(1) as pool, pytest.warns(UserWarning, match="damaged"):
        results = run_trials(tasks, trial_maps, pool, progress=False, journal=path)
    assert ran == [2] and [r.task for r in results] == tasks
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the damaged record was dropped: said once only
        assert list(read_journal(path)) == [_journal_task(i) for i in (0, 1, 3, 4, 2)]


def test_a_customised_profile_travels_with_its_trials():
    """A trial plans with the settings of the profile it was made from, not with the
    default profile of the same name (the worker gets the whole Profile)."""
    capped = PROFILE.with_(planner=replace(PROFILE.planner, max_expansions=1))
    hill = get_world("hill", capped)
    [query] = hill_queries(hill, 1, capped.experiments, seed=0)
    [task] = trial_tasks("experiment1", "hill", "carla_cola", [query], ["binary"], capped)
    result = run_trial(task, trial_maps)
    assert result.outcome.reason == "no_path", result.outcome
    assert result.expansions <= 1
    planner, _, _ = trials._planner("hill", "binary", "carla_cola", PROFILE, trial_maps)
    assert planner.plan(query.start, query.goal).expansions > 1  # the default plans on


def test_the_command_printed_for_a_missing_experiment_builds_that_very_experiment(
        tmp_path, monkeypatch):
    """A study that finds no cached experiment prints the ``dgt reproduce`` command; run as
    printed, it must build the file the study looks for (seed and overrides included)."""
    from dgt_lib.app.cli import _profile, build_parser

    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    prof = get_profile("smoke").with_(seed=3).with_overrides(
        {"experiments.controller": "robust", "experiments.eval_hazard_world": True})
    assert stored_experiment("experiment3", prof) is None
    command = reproduce_command(prof)
    assert command.startswith("dgt reproduce --profile smoke --seed 3 --stages experiments")
    args = build_parser().parse_args(command.split()[1:])
    rebuilt = _profile(args).with_(seed=args.seed)
    assert experiment_path("experiment3", rebuilt) == experiment_path("experiment3", prof)
    assert experiment_path("experiment3", prof).name.startswith("experiment3.")


def test_a_variant_keeps_its_results_apart_from_the_profiles_own(tmp_path, monkeypatch):
    """Trying β = 50 from a notebook's SETTINGS (or --set) must not overwrite the default
    results, and going back to the default must find them again."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    smoke = get_profile("smoke")
    beta = smoke.planner.beta
    assert experiment_stem("experiment1", smoke) == "experiment1"
    b50 = experiment_stem("experiment1", smoke.with_overrides({"planner.beta": 50}))
    b60 = experiment_stem("experiment1", smoke.with_overrides({"planner.beta": 60}))
    assert b50.startswith("experiment1.") and b60.startswith("experiment1.") and b50 != b60
    assert experiment_stem("experiment1", smoke.with_overrides({"planner.beta": beta})) == (
        "experiment1")  # the same trials as the default: the same results
    assert experiment_stem("experiment2", smoke.with_overrides({"experiments.n_hill": 9})) != (
        "experiment2")  # the experiments section keys every experiment
    assert experiment_stem("experiment1", smoke.with_(seed=2)) == "experiment1"


def test_the_jeep_is_asked_exactly_the_vans_ridge_queries_and_keeps_its_own_results():
    """Experiment 2's other half: the jeep drives the van's queries, not new ones, and its
    trials are cached apart, so adding it leaves the van's stored trials valid."""
    from dgt_lib.evaluation.experiments import EXPERIMENTS, experiment_queries
    from dgt_lib.stages.experiments import experiment_config

    prof = get_profile("demo")
    van = experiment_queries("experiment2", prof, load_maps=trial_maps)["mercedes_van"]
    jeep = experiment_queries("experiment2_jeep", prof, load_maps=trial_maps)["jeep"]
    assert [(q.start, q.goal, q.label) for q in jeep] == [(q.start, q.goal, q.label) for q in van]
    assert EXPERIMENTS["experiment2_jeep"][:2] == ("ridge", ("jeep",))
    assert experiment_config("experiment2", prof) != experiment_config("experiment2_jeep", prof)
    assert experiment_stem("experiment2_jeep", prof) == "experiment2_jeep"


def test_a_recorded_trial_stepped_again_ends_as_it_was_recorded(monkeypatch):
    """`step_trial` (notebook 07) drives the trial the experiment drove: same controller,
    seed and time limit, so the same outcome at the same time."""
    from dgt_lib.mapping.world_maps import WorldMaps
    from dgt_lib.perception.bev import BEVMap

    world = from_heightmap(np.zeros((100, 200), np.float32), 0.4, name="flat")
    monkeypatch.setattr(trials, "get_world", lambda name, prof: world)
    grid = world.grid
    bev = BEVMap(grid, np.zeros((6, *grid.shape), np.float32), np.ones(grid.shape, bool),
                 np.ones(grid.shape, np.int64))
    maps = WorldMaps("flat", bev, np.zeros(grid.shape, np.uint8), 0.6, {})
    prof = PROFILE.with_overrides({"mppi.batch_size": 128})
    task = TrialTask("experiment2_jeep", "flat", "binary", "jeep",
                     Query((10.0, 20.0, 0.0), (60.0, 20.0), "northbound"), 3, prof, 0)
    recorded = run_trial(task, lambda *args: maps)
    assert recorded.outcome.reason == "success"
    steps, mppi, rule = trials.step_trial(recorded, maps, keep_every=20)
    assert steps[-1].outcome.reason == recorded.outcome.reason
    assert steps[-1].outcome.duration_s == pytest.approx(recorded.outcome.duration_s)
    assert len(mppi) >= 2 and all(p.shape[1] >= 2 for p in mppi.values())
