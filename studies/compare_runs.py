"""Did a rerun give the same artifacts? Compares two data directories of one profile, seed by seed.

    DGT_DATA_DIR=/tmp/fresh dgt reproduce --profile paper --seeds 1
    .venv/bin/python studies/compare_runs.py data /tmp/fresh --profile paper --seed 0

For each run seed (``--seed S``, default 0; ``--seeds N``: 0 … N-1, a table each) and each
artifact group of ``<dir>/<profile>/seed-<seed>/`` present in both directories — episodes,
BEV maps, the dataset, models, slope fit and τ_s, costmaps, the accuracy scores and the
experiments' counts — prints how many files are bit-identical and names the first that
differ. Arrays are compared with NaN equal to NaN, checkpoints by their weights (not their
training history, whose epoch times differ), the experiments by the counts, routes and
failure reasons of ``results/summary.json``. MuJoCo is deterministic on one machine, not
across machines: on another machine expect the episodes to differ from the start.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
from runner import Study

GROUPS: tuple[tuple[str, str], ...] = (
    ("episodes", "episodes/*.npz"),
    ("BEV maps", "bev/*.npz"),
    ("dataset", "dataset.npz"),
    ("models", "models/*.pt"),
    ("slope-based fit", "baselines/*.json"),
    ("τ_s", "occupancy/*.json"),
    ("costmaps", "costmaps/*/*.npz"),
    ("accuracy", "accuracy/costmaps.json"),
    ("experiments (counts, routes, reasons)", "results/summary.json"),
)
"""(name, glob under the seed directory) of each compared group."""


def _same_npz(a: Path, b: Path) -> bool:
    with np.load(a) as x, np.load(b) as y:
        if sorted(x.files) != sorted(y.files):
            return False
        for k in x.files:
            u, v = x[k], y[k]
            nan_ok = u.dtype.kind in "fc"
            if u.shape != v.shape or not np.array_equal(u, v, equal_nan=nan_ok):
                return False
    return True


def _same_checkpoint(a: Path, b: Path) -> bool:
    import torch

    x = torch.load(a, map_location="cpu", weights_only=False)["state_dict"]
    y = torch.load(b, map_location="cpu", weights_only=False)["state_dict"]
    return x.keys() == y.keys() and all(torch.equal(x[k], y[k]) for k in x)


def _same_json(a: Path, b: Path) -> bool:
    x, y = json.loads(a.read_text()), json.loads(b.read_text())
    if a.name == "summary.json":  # the experiments' outcomes, not the model metrics' floats
        x, y = x.get("experiments"), y.get("experiments")
    return x == y


COMPARE: dict[str, Callable[[Path, Path], bool]] = {
    ".npz": _same_npz, ".pt": _same_checkpoint, ".json": _same_json}


def compare(first: Path, second: Path) -> list[tuple[str, int, int, list[str]]]:
    """Per group: (name, files in both, identical, names of the differing files)."""
    rows = []
    for name, pattern in GROUPS:
        # artifacts only: not their metadata, nor an unfinished training's snapshot
        in_first = {p.relative_to(first) for p in first.glob(pattern)
                    if not p.name.endswith((".meta.json", ".resume.pt"))}
        both = sorted(p for p in in_first if (second / p).exists())
        differ = [str(p) for p in both if not COMPARE[p.suffix](first / p, second / p)]
        rows.append((name, len(both), len(both) - len(differ), differ))
    return rows


def main() -> None:
    study = Study("compare_runs", __doc__, profile="demo", seeds=1, publishes=False)
    study.parser.add_argument("first", type=Path,
                              help="a data directory (what DGT_DATA_DIR names)")
    study.parser.add_argument("second", type=Path)
    args = study.parse()
    for i, seed in enumerate(study.seeds):
        if i:
            print()
        dirs = [d / args.profile / f"seed-{seed}" for d in (args.first, args.second)]
        for d in dirs:
            if not d.is_dir():
                raise SystemExit(f"no run here: {d} (run `dgt reproduce --profile "
                                 f"{args.profile}` with DGT_DATA_DIR pointing at its data "
                                 "directory)")
        print(f"{dirs[0]}  vs  {dirs[1]}\n")
        print("| artifacts | files in both | identical | first that differ |")
        print("| --- | --- | --- | --- |")
        for name, n, same, differ in compare(*dirs):
            shown = ", ".join(differ[:3]) + (f" (+{len(differ) - 3})" if len(differ) > 3
                                             else "")
            print(f"| {name} | {n} | {same} | {shown or '—'} |")


if __name__ == "__main__":
    main()
