"""``studies/log_minutes.py``: logs measured in labelled minutes, the held-out runs apart from
every training run, early stopping on the last quarter of a log's runs, and the tables of the
heads on the truck's ground truth."""

import importlib
import sys
from pathlib import Path

import numpy as np

from dgt_lib.perception.dataset import SPLIT_NAMES, PatchDataset

STUDIES = str(Path(__file__).resolve().parents[1] / "studies")
if STUDIES not in sys.path:  # the study's script and its helpers live there
    sys.path.append(STUDIES)
log_minutes = importlib.import_module("log_minutes")
TRAIN, VAL, TEST = (SPLIT_NAMES.index(s) for s in SPLIT_NAMES)
INTERVAL_S = 0.5  # two patches a second: 120 patches a labelled minute


def _log(patches_per_run: list[int], first_id: int = 7) -> PatchDataset:
    """A log whose run i holds ``patches_per_run[i]`` patches (run ids from ``first_id``)."""
    trajectory = np.repeat(np.arange(len(patches_per_run)) + first_id, patches_per_run)
    n = len(trajectory)
    return PatchDataset(patches=np.zeros((n, 6, 22, 7), np.float16),
                        observed=np.ones((n, 22, 7), bool),
                        labels=np.linspace(0, 1, n, dtype=np.float32),
                        vehicle=np.zeros(n, np.int8), trajectory=trajectory.astype(np.int32),
                        pose=np.zeros((n, 3), np.float32), split=np.zeros(n, np.int8))


def test_a_length_in_labelled_minutes_takes_the_fewest_first_runs_that_hold_it():
    log = _log([60, 120, 240, 30])  # 0.5, 1, 2 and 0.25 labelled minutes
    assert log_minutes.first_runs(log, 0.5, INTERVAL_S) == 1
    assert log_minutes.first_runs(log, 1.0, INTERVAL_S) == 2
    assert log_minutes.first_runs(log, 3.0, INTERVAL_S) == 3  # 3.5 minutes in three runs


def test_several_bag_files_make_one_drive_with_a_run_id_each_in_order():
    drive = log_minutes.concatenate([_log([10, 20], first_id=3), _log([5], first_id=3)])
    assert list(np.unique(drive.trajectory)) == [0, 1, 2]
    assert [int((drive.trajectory == r).sum()) for r in (0, 1, 2)] == [10, 20, 5]


def test_early_stopping_watches_the_last_quarter_of_the_runs_and_never_the_held_out_log():
    log, held_out = _log([10] * 8), _log([4, 4, 4], first_id=100)
    data = log_minutes.study_data(log, held_out, 8)
    runs = np.unique(data.trajectory[data.split != TEST])
    val_runs = np.unique(data.trajectory[data.split == VAL])
    assert list(val_runs) == list(runs[-2:])  # 2 of 8 runs
    assert (data.split == TEST).sum() == 12
    assert not set(data.trajectory[data.split == TEST]) & set(runs)
    one = log_minutes.study_data(log, held_out, 1)  # one run: its last quarter of patches
    assert list(one.split[:10]) == [TRAIN] * 7 + [VAL] * 3
    two = log_minutes.study_data(log, held_out, 2)
    assert (two.split == VAL).sum() == 10 and (two.split == TRAIN).sum() == 10


def test_no_held_out_run_shares_a_run_seed_and_so_a_spawn_with_a_training_run():
    """Run seed k spawns run k: the training runs are 100·S + 1 … 100·S + MAX_RUNS, the
    held-out ones 100·S + HELD_OUT_FIRST …, and seeds S and S + 1 do not meet."""
    training = set(range(1, log_minutes.MAX_RUNS + 1))
    held_out = set(range(log_minutes.HELD_OUT_FIRST,
                         log_minutes.HELD_OUT_FIRST + log_minutes.HELD_OUT_RUNS))
    assert not training & held_out and max(training | held_out) < 100


def _truth(seed: int) -> dict:
    """One seed's ``truth_and_plans`` scores: head i's MAE 0.1·(i+1) + 0.01·seed on the hill
    (twice that on the ridge); the zero-shot head plans every ascent by Route A, the others
    one fewer per seed."""
    out = {"seed": seed, "prior_label": 0.6}
    for i, head in enumerate(log_minutes.HEADS):
        a = 3 if head == "zero-shot" else 3 - seed
        out[head] = {
            "hill": {"mae": 0.1 * (i + 1) + 0.01 * seed, "samples": 50,
                     "routes": [["ascent", "A"]] * a + [["ascent", "B"]] * (3 - a)
                     + [["descent", "B"]] * 3},
            "ridge": {"mae": 0.2 * (i + 1) + 0.02 * seed, "samples": 40,
                      "routes": [["northbound", "smooth"], ["southbound", "sharp"],
                                 ["northbound", None]]}}
    return out


def test_the_truth_tables_give_each_heads_mae_per_world_and_its_plans_per_seed():
    tables = log_minutes.truth_tables([_truth(0), _truth(1)])
    assert tables["truth"]["columns"] == ["head", "hill MAE", "ridge MAE"]
    assert tables["truth"]["rows"][0] == ["prior", "0.105 (0.100, 0.110)",
                                          "0.210 (0.200, 0.220)"]
    plans = {row[0]: row[1:] for row in tables["plans"]["rows"]}
    assert plans["zero-shot"] == ["3/3, 3/3", "3/3, 3/3", "1/3, 1/3"]  # no path: not smooth
    assert plans["few-shot"][0] == "3/3, 2/3"
