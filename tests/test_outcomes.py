"""Trial outcomes (dgt_lib.navigation.outcome) and success-rate statistics
(dgt_lib.evaluation.statistics, dgt_lib.evaluation.paper)."""

import math

import numpy as np
import pytest
from scipy.stats import binomtest

from dgt_lib.evaluation.paper import PAPER_TABLE_I, PAPER_TABLE_II
from dgt_lib.evaluation.statistics import (
    markdown_table,
    reason_counts,
    success_rows,
    wilson_interval,
)
from dgt_lib.navigation.outcome import (
    GOAL_TOLERANCE_M,
    IMMOBILE_SPEED_MPS,
    IMMOBILE_TIME_S,
    REASONS,
    OutcomeRule,
    TrialOutcome,
)
from dgt_lib.world.simulator import immobile_time

DT = 0.05  # s


def evaluate_trial(  # the rule applied offline, as drive applies it online
    times,
    positions,
    speeds,
    goal,
    flipped=None,
    diverged=None,
    path_found: bool = True,
    goal_tolerance_m: float = GOAL_TOLERANCE_M,
    immobile_speed_mps: float = IMMOBILE_SPEED_MPS,
    immobile_time_s: float = IMMOBILE_TIME_S,
) -> TrialOutcome:
    """Judge a recorded trace with :class:`OutcomeRule`, sample by sample.

    ``times`` (T,) [s], ``positions`` (T, 2 or 3) [m], ``speeds`` (T,) [m/s],
    ``goal`` (x, y[, …]) [m]; optional boolean ``flipped`` / ``diverged`` (T,).
    No event by the end of the trace means ``timeout`` (a loop stops a trial at its
    time limit). ``path_found=False`` gives ``no_path`` without looking at the trace.
    """
    if not path_found:
        return TrialOutcome.failure("no_path")
    t = np.asarray(times, dtype=np.float64)
    p = np.asarray(positions, dtype=np.float64)
    v = np.asarray(speeds, dtype=np.float64)
    if t.ndim != 1 or len(t) == 0 or p.shape[0] != len(t) or v.shape != t.shape:
        raise ValueError(f"need T ≥ 1 samples of times, positions and speeds, got "
                         f"{t.shape}, {p.shape}, {v.shape}")
    flags = {}
    for name, f in (("flipped", flipped), ("diverged", diverged)):
        if f is not None:
            f = np.asarray(f, dtype=bool)
            if f.shape != t.shape:
                raise ValueError(f"{name} must have shape {t.shape}, got {f.shape}")
            flags[name] = f
    g = np.asarray(goal, dtype=np.float64)[:2]
    rule = OutcomeRule(goal_tolerance_m, immobile_time_s)
    immobile = 0.0
    for i in range(len(t)):
        dt = t[i] - t[i - 1] if i else 0.0
        immobile = immobile_time(immobile, v[i], dt, immobile_speed_mps)
        done = next((name for name, f in flags.items() if f[i]), None)
        outcome = rule.judge(float(t[i] - t[0]), p[i], g, immobile, done)
        if outcome is not None:
            return outcome
    return TrialOutcome(False, "timeout", float(t[-1] - t[0]),
                        float(np.hypot(*(p[-1, :2] - g))))



def drive(speeds, start=(0.0, 0.0)):
    """A straight trace along +x at the given speeds [m/s], one sample per DT."""
    v = np.asarray(speeds, dtype=float)
    t = DT * np.arange(len(v))
    x = start[0] + np.concatenate([[0.0], np.cumsum(v[:-1] * DT)])
    return t, np.stack([x, np.full_like(x, start[1]), np.zeros_like(x)], axis=1), v


# ----------------------------------------------------------------------------- criteria


def test_paper_criteria_constants():
    assert GOAL_TOLERANCE_M == 5.0 and IMMOBILE_TIME_S == 10.0
    assert 0.0 < IMMOBILE_SPEED_MPS < 1.0
    assert set(REASONS) == {
        "success", "immobilized", "flipped", "timeout", "no_path", "diverged", "error"
    }


def test_success_when_within_5_m_of_the_goal():
    t, pos, v = drive(np.full(400, 5.0))  # 0 → ~100 m in 20 s
    out = evaluate_trial(t, pos, v, goal=(60.0, 0.0))
    assert out.success and out.reason == "success"
    # 55 m at 5 m/s: the first sample within 5 m of the goal.
    assert out.duration_s == pytest.approx(11.0, abs=DT)
    assert out.goal_distance_m <= 5.0
    # A goal 6 m to the side is never reached: timeout at the end of the trace.
    out = evaluate_trial(t, pos, v, goal=(60.0, 6.0))
    assert not out.success and out.reason == "timeout"
    assert out.duration_s == pytest.approx(t[-1])
    assert out.goal_distance_m == pytest.approx(math.hypot(pos[-1, 0] - 60.0, 6.0))
    # 2-D positions work too.
    assert evaluate_trial(t, pos[:, :2], v, goal=(60.0, 0.0)).success


def test_immobilized_only_after_more_than_10_s_continuously_slow():
    slow = IMMOBILE_SPEED_MPS / 2
    # 9.5 s stuck, then it drives on to the goal: a success.
    t, pos, v = drive(np.r_[np.full(20, 3.0), np.full(190, slow), np.full(400, 5.0)])
    assert evaluate_trial(t, pos, v, goal=(80.0, 0.0)).success
    # 10.5 s stuck: immobilized, decided just after 10 s of standstill.
    t, pos, v = drive(np.r_[np.full(20, 3.0), np.full(210, slow), np.full(400, 5.0)])
    out = evaluate_trial(t, pos, v, goal=(80.0, 0.0))
    assert out.reason == "immobilized" and not out.success
    assert out.duration_s == pytest.approx(20 * DT + IMMOBILE_TIME_S, abs=2 * DT)
    # Two 6 s stops separated by motion never add up.
    t, pos, v = drive(np.r_[np.full(120, slow), np.full(20, 3.0), np.full(120, slow)])
    assert evaluate_trial(t, pos, v, goal=(500.0, 0.0)).reason == "timeout"
    # Rolling backwards is motion: the magnitude of the speed counts.
    t, pos, v = drive(np.full(300, -1.0))
    assert evaluate_trial(t, pos, v, goal=(500.0, 0.0)).reason == "timeout"


def test_flips_and_divergence_end_a_trial_and_the_earliest_event_wins():
    t, pos, v = drive(np.full(400, 5.0))
    flipped = np.zeros(len(t), bool)
    flipped[100:] = True  # flips at 5 s, before reaching the goal at 11 s
    out = evaluate_trial(t, pos, v, goal=(60.0, 0.0), flipped=flipped)
    assert out.reason == "flipped" and out.duration_s == pytest.approx(5.0)
    flipped[:] = False
    flipped[300:] = True  # flips after the success: still a success
    assert evaluate_trial(t, pos, v, goal=(60.0, 0.0), flipped=flipped).success
    diverged = np.zeros(len(t), bool)
    diverged[220] = True  # same sample as the goal reach: the goal is checked first
    assert evaluate_trial(t, pos, v, goal=(60.0, 0.0), diverged=diverged).success
    diverged[219] = True  # one sample earlier: the failure
    assert evaluate_trial(t, pos, v, goal=(60.0, 0.0), diverged=diverged).reason == "diverged"
    with pytest.raises(ValueError, match="shape"):
        evaluate_trial(t, pos, v, goal=(60.0, 0.0), flipped=flipped[:-1])


def test_no_path_and_input_checks():
    out = evaluate_trial([], np.zeros((0, 2)), [], goal=(0, 0), path_found=False)
    assert out == TrialOutcome(False, "no_path", 0.0)
    with pytest.raises(ValueError):
        evaluate_trial([], np.zeros((0, 2)), [], goal=(0, 0))
    with pytest.raises(ValueError, match="unknown reason"):
        TrialOutcome(False, "crashed", 1.0)
    with pytest.raises(ValueError, match="contradicts"):
        TrialOutcome(True, "timeout", 1.0)
    err = TrialOutcome.failure("error", 3.0, detail="RuntimeError('boom')")
    assert not err.success and err.detail.startswith("RuntimeError")


def test_the_immobility_clock_counts_continuous_slow_time():
    assert immobile_time(0.0, 0.0, 0.05) == pytest.approx(0.05)
    assert immobile_time(9.0, -0.1, 1.0) == pytest.approx(10.0)  # |speed| counts
    assert immobile_time(9.0, IMMOBILE_SPEED_MPS, 1.0) == 0.0  # at the threshold: moving
    assert immobile_time(9.0, -1.0, 1.0) == 0.0


def test_the_online_rule_decides_at_the_same_sample_as_a_replayed_trace():
    # 3 s driving, a 4 s stop, 1 s driving, then a 12 s stop starting at t = 8 s.
    speeds = np.r_[np.full(60, 2.0), np.zeros(80), np.full(20, 2.0), np.full(240, 0.1)]
    times = DT * np.arange(len(speeds))
    rule, immobile, online = OutcomeRule(), 0.0, None
    for i in range(len(times)):
        immobile = immobile_time(immobile, speeds[i], DT if i else 0.0)
        if rule.judge(times[i], (0.0, 0.0), (500.0, 0.0), immobile) is not None:
            online = i
            break
    assert online == 160 + 200  # the clock adds each slow step's 0.05 s: > 10 s after 201
    out = evaluate_trial(times, np.zeros((len(times), 2)), speeds, goal=(500.0, 0.0))
    assert out.reason == "immobilized" and out.duration_s == pytest.approx(times[online])


def test_rule_order_goal_then_simulator_end_then_immobile_then_time():
    rule = OutcomeRule(goal_tolerance_m=5.0, immobilized_limit_s=10.0, time_limit_s=60.0)
    assert rule.judge(70.0, (1.0, 0.0), (0.0, 0.0), 20.0, "flipped").success
    assert rule.judge(70.0, (9.0, 0.0), (0.0, 0.0), 20.0, "flipped").reason == "flipped"
    assert rule.judge(70.0, (9.0, 0.0), (0.0, 0.0), 20.0, "off_map").reason == "diverged"
    assert rule.judge(70.0, (9.0, 0.0), (0.0, 0.0), 20.0).reason == "immobilized"
    assert rule.judge(70.0, (9.0, 0.0), (0.0, 0.0), 5.0).reason == "timeout"
    assert rule.judge(30.0, (9.0, 0.0), (0.0, 0.0), 5.0) is None
    assert rule.judge(30.0, (0.0, 0.0), None, 5.0) is None  # no goal: never a success


# ----------------------------------------------------------------------------- statistics


@pytest.mark.parametrize(
    "k, n, expected",
    [(16, 20, (0.584, 0.919)), (0, 10, (0.0, 0.2775)), (47, 50, (0.838, 0.979))],
)
def test_wilson_interval_known_values(k, n, expected):
    lo, hi = wilson_interval(k, n)
    assert lo == pytest.approx(expected[0], abs=5e-4)
    assert hi == pytest.approx(expected[1], abs=5e-4)


@pytest.mark.parametrize("k, n", [(0, 1), (1, 1), (3, 7), (70, 100), (54, 99), (35, 99)])
@pytest.mark.parametrize("confidence", [0.9, 0.95, 0.99])
def test_wilson_interval_matches_scipy(k, n, confidence):
    ref = binomtest(k, n).proportion_ci(confidence_level=confidence, method="wilson")
    lo, hi = wilson_interval(k, n, confidence)
    assert lo == pytest.approx(ref.low, abs=1e-12)
    assert hi == pytest.approx(ref.high, abs=1e-12)
    assert 0.0 <= lo <= k / n <= hi <= 1.0


def test_wilson_interval_rejects_bad_counts():
    for k, n in [(-1, 5), (6, 5), (0, 0)]:
        with pytest.raises(ValueError):
            wilson_interval(k, n)
    with pytest.raises(TypeError):
        wilson_interval(0.5, 10)
    with pytest.raises(ValueError):
        wilson_interval(1, 10, confidence=1.0)


def test_paper_tables_are_the_published_counts():
    hill, ridge = PAPER_TABLE_I["hill"], PAPER_TABLE_I["ridge"]
    assert (hill.vehicle, hill.n, ridge.vehicle, ridge.n) == ("carla_cola", 20, "mercedes_van", 50)
    assert hill.k == {"dgt": 16, "isotropic": 10, "single-task": 5,
                      "slope": 16, "binary": 10}
    assert ridge.k == {"dgt": 47, "isotropic": 45, "single-task": 14,
                       "slope": 26, "binary": 20}
    assert {v: (r.n, r.k) for v, r in PAPER_TABLE_II.items()} == {
        "jeep": (100, {"dgt": 70, "single-task": 64}),
        "vw_van": (99, {"dgt": 54, "single-task": 35}),
    }
    # The success rates printed in the paper: 80/50/25/80/50 %, 54.5 % and 35.4 %.
    def paper_rows(result):  # the paper's own counts as rows with Wilson intervals
        return success_rows({m: (k, result.n) for m, k in result.k.items()})

    assert [r["sr_pct"] for r in paper_rows(hill)] == [80.0, 50.0, 25.0, 80.0, 50.0]
    assert [round(r["sr_pct"], 1) for r in paper_rows(PAPER_TABLE_II["vw_van"])] == [54.5, 35.4]


def test_results_rows_and_markdown_table():
    outcomes = [TrialOutcome(True, "success", 30.0)] * 3 + [
        TrialOutcome.failure("immobilized", 40.0),
        TrialOutcome.failure("flipped", 12.0),
    ]
    counts = reason_counts(outcomes)
    assert list(counts) == list(REASONS)
    assert counts["success"] == 3 and counts["immobilized"] == 1 and counts["timeout"] == 0

    hill = PAPER_TABLE_I["hill"]
    rows = success_rows({"dgt": (3, 5), "mine": (0, 5)}, paper=hill.k, paper_n=hill.n)
    assert rows[0]["method"] == "dgt" and rows[0]["sr_pct"] == 60.0
    lo, hi = wilson_interval(3, 5)
    assert (rows[0]["ci_low_pct"], rows[0]["ci_high_pct"]) == (100 * lo, 100 * hi)
    assert rows[0]["paper_k"] == 16 and rows[0]["paper_sr_pct"] == 80.0
    assert rows[1]["paper_k"] is None
    table = markdown_table(rows, title="Hill (carla_cola)")
    lines = table.strip().splitlines()
    assert lines[0] == "**Hill (carla_cola)**"
    assert lines[2].startswith("| method | k / n | SR % | 95 % CI % | paper k")
    assert lines[4] == f"| DGT-Map | 3 / 5 | 60.0 | {100 * lo:.1f}–{100 * hi:.1f} | 16 | 80.0 |"
    assert lines[5].startswith("| mine | 0 / 5 | 0.0 | 0.0–") and lines[5].endswith("| — | — |")
    assert "paper" not in markdown_table(success_rows({"binary": (1, 2)}))
    with pytest.raises(ValueError, match="paper_n"):
        success_rows({"dgt": (1, 2)}, paper=hill.k)
