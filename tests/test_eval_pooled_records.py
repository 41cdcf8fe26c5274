"""``studies/eval_pooled.py``'s record: PooledNet beside DGTNet against the ground truth,
from per-seed results in the shape the study saves them."""

import importlib
import math
import sys
from pathlib import Path

STUDIES = str(Path(__file__).resolve().parents[1] / "studies")
if STUDIES not in sys.path:  # the study's script and its helpers live there
    sys.path.append(STUDIES)
eval_pooled = importlib.import_module("eval_pooled")


def _seed(seed: int, pooled_mae: float) -> dict:
    """One seed's saved results: DGTNet's MAE on the hill 0.20, PooledNet's ``pooled_mae``;
    the ridge has no cell with a harder direction (sign agreement undefined)."""
    def row(world, vehicle, method, mae, sign):
        return {"world": world, "vehicle": vehicle, "method": method, "mae": mae,
                "spearman": 0.5, "sign_agreement": sign, "shape": [10, 10],
                **({"dense_s": 1.5, "dense_cpu_s": 2.9} if method == "pooled" else {})}
    mse = {v: {"mse": 0.01, "spearman": 0.4} for v in ("jeep", "carla_cola")}
    return {"seed": seed, "params": 53380, "train_s": 50.0, "uptime": ["0.5", "1", "1"],
            "architecture": {"width": 32, "depth": 6, "fc_hidden": 64},
            "test": {"pooled": mse, "dgt": mse},
            "accuracy": [row("hill", "carla_cola", "dgt", 0.20, 0.75),
                         row("hill", "carla_cola", "pooled", pooled_mae, 0.5),
                         row("ridge", "jeep", "dgt", 0.02, math.nan),
                         row("ridge", "jeep", "pooled", 0.03, math.nan)]}


def test_the_accuracy_table_counts_the_seeds_where_poolednet_is_closer_to_the_truth():
    tab = eval_pooled._accuracy_table([_seed(0, 0.10), _seed(1, 0.30), _seed(2, 0.15)])
    hill, ridge = tab["rows"]
    assert hill[:4] == ["hill, carla_cola", "0.200", "0.183", "2 of 3"]
    assert hill[-1] == "75 / 75 / 75 · 50 / 50 / 50 (%)"
    assert ridge[3] == "0 of 3" and ridge[-1] == "— / — / — · — / — / — (%)"


def test_the_times_table_has_one_row_per_seed_with_each_world_dense():
    tab = eval_pooled._times_table([_seed(0, 0.1), _seed(4, 0.1)])
    assert [r[0] for r in tab["rows"]] == ["0", "4"]
    assert tab["columns"][3:5] == ["hill dense", "ridge dense"]
    assert tab["rows"][0][3] == "1.5 / 2.9" and "depth 6" in tab["title"]


def test_the_sizes_table_sets_each_size_beside_dgtnet_and_counts_its_test_wins():
    small = [_seed(0, 0.10), _seed(1, 0.30)]
    large = [{**_seed(s, 0.12), "architecture": {"width": 64, "depth": 4, "fc_hidden": 64}}
             for s in (0, 1)]
    for r in large:  # the larger net beats DGTNet's test MSE for the jeep alone
        r["test"] = {"pooled": {"jeep": {"mse": 0.005, "spearman": 0.4},
                                "carla_cola": {"mse": 0.02, "spearman": 0.4}},
                     "dgt": r["test"]["dgt"]}
    tab = eval_pooled._sizes_table([small, large])
    assert tab["columns"][1:] == ["DGT-Map (DGTNet)", "PooledNet width 32, depth 6",
                                  "PooledNet width 64, depth 4"]
    hill = tab["rows"][0]
    assert hill == ["hill, carla_cola", "0.200", "0.200", "0.120"]
    assert tab["rows"][-1] == ["test MSE below DGTNet's", "—", "0 of 4 vehicle-seeds",
                               "2 of 4 vehicle-seeds"]
