"""Costmap accuracy against the ground truth: MAE, Spearman ρ, directional contrast
(dgt_lib.evaluation.accuracy)."""

import math

import numpy as np
import pytest

from dgt_lib.core.geometry import GridSpec
from dgt_lib.evaluation.accuracy import (
    accuracy_over_seeds,
    accuracy_table,
    contrast_pairs,
    cost_at,
    costmap_accuracy,
    free_cells,
    multitask_comparisons,
    multitask_over_seeds,
    multitask_table,
    paired_comparison,
)

K = 8


@pytest.fixture
def truth():
    """(N, K) C*: cell 0 flat (cheap every way), cell 1 a slope (uphill k = 2 costly,
    downhill k = 6 cheap), cell 2 rough (costly every way); one sample unmeasured."""
    c = np.full((3, K), 0.05)
    c[1, 1:4], c[1, 5:8] = (0.6, 0.95, 0.6), (0.1, 0.1, 0.1)
    c[2] = 0.7
    valid = np.ones_like(c, bool)
    valid[0, 5] = False
    c[0, 5] = np.nan
    return c, valid


def test_a_perfect_map_scores_zero_error_full_rank_and_the_truths_contrast(truth):
    c, valid = truth
    r = costmap_accuracy(c, np.nan_to_num(c), valid)
    assert r["n"] == 23 and r["mae"] == 0 and r["spearman"] == pytest.approx(1.0)
    assert r["pairs"] == 3  # cell 1: (θ1, θ5), (θ2, θ6), (θ3, θ7); not cell 0's NaN pair
    assert r["contrast"] == r["contrast_true"] == pytest.approx(np.mean([0.5, 0.85, 0.5]))
    assert r["sign_agreement"] == 1.0


def test_an_isotropic_map_has_no_contrast_and_a_reversed_one_the_wrong_sign(truth):
    c, valid = truth
    iso = np.repeat(np.nanmean(c, axis=1, keepdims=True), K, axis=1)
    r = costmap_accuracy(c, iso, valid)
    assert r["contrast"] == 0 and r["sign_agreement"] == 0 and r["mae"] > 0
    reversed_ = np.roll(np.nan_to_num(c), K // 2, axis=1)  # uphill and downhill swapped
    r = costmap_accuracy(c, reversed_, valid)
    assert r["sign_agreement"] == 0 and r["contrast"] == pytest.approx(r["contrast_true"])
    constant = np.zeros_like(c)  # the binary map: no ranking at all
    r = costmap_accuracy(c, constant, valid)
    assert math.isnan(r["spearman"]) and r["mae"] == pytest.approx(np.nanmean(c))


def test_pairs_need_both_headings_measured_and_a_difference_above_the_threshold(truth):
    c, valid = truth
    i, k = contrast_pairs(c, valid, 0.3)
    assert list(zip(i.tolist(), k.tolist(), strict=True)) == [(1, 1), (1, 2), (1, 3)]
    assert len(contrast_pairs(c, valid, 0.6)[0]) == 1
    with pytest.raises(ValueError, match="even K"):
        contrast_pairs(c[:, :7], valid[:, :7])


def test_costs_are_read_at_the_cell_and_heading_layer_and_one_layer_serves_all():
    grid = GridSpec((0.0, 0.0), 0.5, (4, 6))
    cost = np.arange(K * 24, dtype=np.float32).reshape(K, 4, 6)
    cells = np.array([[0.25, 0.25], [2.75, 1.25]])  # cells (0, 0) and (2, 5)
    got = cost_at(cost, grid, cells, K)
    np.testing.assert_array_equal(got[:, 3], [cost[3, 0, 0], cost[3, 2, 5]])
    one = cost_at(cost[:1], grid, cells, K)
    assert one.shape == (2, K) and (one == one[:, :1]).all()
    with pytest.raises(ValueError, match="K = 8 or 1"):
        cost_at(cost[:4], grid, cells, K)
    occ = np.zeros((4, 6), np.uint8)
    occ[2, 5] = 1
    assert free_cells(occ, grid, cells).tolist() == [True, False]


def _row(world, vehicle, method, n, mae, rho):
    return {"world": world, "vehicle": vehicle, "method": method, "n": n, "mae": mae,
            "spearman": rho, "pairs": 0, "contrast_true": math.nan, "contrast": math.nan,
            "sign_agreement": math.nan}


def test_multi_task_and_single_task_are_compared_on_the_same_samples_with_a_paired_test():
    rng = np.random.default_rng(0)
    truth = {w: rng.uniform(0, 1, 60) for w in ("ridge", "eval")}
    noise = {w: rng.normal(0, 0.05, 60) for w in truth}
    samples = {}
    for w, t in truth.items():  # multi-task: small errors; single-task: larger, same samples
        samples[(w, "jeep", "dgt")] = (t + noise[w], t)
        samples[(w, "jeep", "single-task")] = (t + 4 * noise[w], t)
    t = truth["eval"]
    samples[("eval", "vw_van", "dgt")] = (t + noise["eval"], t)
    samples[("eval", "vw_van", "single-task")] = (t - noise["eval"], t)  # as close
    samples[("hill", "carla_cola", "dgt")] = (t, t)  # no single-task map: not compared
    jeep, vw_van = multitask_comparisons(samples)
    assert jeep["vehicle"] == "jeep" and jeep["worlds"] == ["ridge", "eval"]
    assert jeep["n"] == 120 and jeep["closer"] == "multi-task" and jeep["p"] < 1e-6
    assert jeep["mae_a"] == pytest.approx(np.mean(np.abs(np.concatenate(list(noise.values())))))
    assert vw_van["closer"] == "neither" and vw_van["p"] > 0.05  # the same |errors|
    table = multitask_table([jeep, vw_van])
    assert "| jeep | ridge, eval | 120 |" in table and "| < 0.001 | multi-task |" in table
    assert table.splitlines()[3].endswith("| neither |")
    t = truth["eval"]  # two nearly constant maps a hair apart: significant, no difference
    hair = {("eval", "jeep", "dgt"): (t * 0 + 0.9, t),
            ("eval", "jeep", "single-task"): (t * 0 + 0.9001, t)}
    (c,) = multitask_comparisons(hair)
    assert c["p"] < 0.05 and c["closer"] == "neither"
    same = paired_comparison(np.zeros(5), np.zeros(5), np.ones(5))
    assert same["p"] == 1.0 and same["mae_a"] == same["mae_b"] == 1.0
    swapped = {(w, v, "single-task" if m == "dgt" else "dgt"): x
               for (w, v, m), x in samples.items() if v == "jeep"}
    assert multitask_comparisons(swapped)[0]["closer"] == "single-task"
    over = multitask_over_seeds({0: [jeep, vw_van], 1: [{**jeep, "closer": "neither"}]})
    assert "| jeep |" in over and over.splitlines()[2].endswith("| 1 of 2 seeds |")
    assert over.splitlines()[3].endswith("| — | 0 of 1 seed |")


def test_tables_of_every_method_per_seed_and_over_seeds():
    rows = [_row("ridge", "jeep", "dgt", 10, 0.1, 0.5), _row("eval", "jeep", "binary", 30, 0.2,
                                                              math.nan)]
    table = accuracy_table(rows)
    assert "| ridge | jeep | DGT-Map | 10 | 0.100 | 0.50 | 0 | — | — | — |" in table
    assert "| eval | jeep | Binary | 30 | 0.200 | — |" in table
    over = accuracy_over_seeds({0: rows, 1: [_row("ridge", "jeep", "dgt", 10, 0.3, 0.7)]})
    assert "| ridge | jeep | DGT-Map | 0.100 / 0.50 | 0.300 / 0.70 | 0.200 | 0.60 |" in over
    assert "| eval | jeep | Binary | 0.200 / — | — | 0.200 | — |" in over
