"""The densely evaluable PooledNet against DGT-Map's multi-task DGTNet, on a profile's cached data.

For each run seed: train :class:`~dgt_lib.beyond.pooled.PooledNet` with the profile's own
training recipe (``profile.train``: epochs, batch size, learning rate, schedule, selection,
mirror augmentation) through :func:`~dgt_lib.beyond.pooled.train_pooled`, on the seed's
dataset with each patch re-cut with its context margin from the training world's BEV (same
poses, labels and train/val/test split); then report

- test MSE / Spearman ρ per vehicle beside the seed's cached multi-task DGTNet;
- the accuracy against the measured ground truth on hill / ridge / eval (as
  ``eval_equivariant.py``: MAE, Spearman ρ, directional contrast) beside the cached DGT-Map
  costmaps, the PooledNet's costmaps made by dense evaluation;
- the dense costmap's time per world (all 8 headings, 4 vehicles).

Nothing of the profile is rebuilt (it stops if an artifact is not cached fresh). Results go
to ``data/pooled/``.

    DGT_DATA_DIR=... python studies/eval_pooled.py --profile demo --seeds 3
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import torch  # noqa: E402
from eval_equivariant import (  # noqa: E402
    accuracy_lines,
    ground_truth_accuracy,
    run_seeds,
    test_lines,
)
from runner import Study  # noqa: E402

from dgt_lib.beyond import pooled  # noqa: E402
from dgt_lib.beyond.dense import directional_costmap_dense  # noqa: E402
from dgt_lib.core import artifacts  # noqa: E402
from dgt_lib.core.config import VEHICLES  # noqa: E402
from dgt_lib.learning.checkpoints import load_checkpoint  # noqa: E402
from dgt_lib.learning.training import evaluate  # noqa: E402
from dgt_lib.perception.dataset import TEST, TRAIN  # noqa: E402
from dgt_lib.stages.collect import ensure_bev  # noqa: E402
from dgt_lib.stages.dataset import ensure_dataset  # noqa: E402
from dgt_lib.stages.paths import data_dir  # noqa: E402
from dgt_lib.stages.train import model_relpath  # noqa: E402


def run_seed(prof, args) -> dict:
    ds = ensure_dataset(prof, progress=False)
    bev = ensure_bev("training", prof, progress=False)
    out_dir = artifacts.data_root() / "pooled"
    out_dir.mkdir(parents=True, exist_ok=True)
    model_path = out_dir / f"pooled{args.tag}_{prof.name}_seed{prof.seed}.pt"
    torch.manual_seed(prof.seed)
    model = pooled.PooledNet(VEHICLES, width=args.width, depth=args.depth,
                             fc_hidden=args.fc_hidden)
    crops = pooled.context_dataset(ds, bev, model.margin)
    if args.reuse:
        model.load_state_dict(torch.load(model_path, weights_only=True))
        old = json.loads((out_dir / f"results{args.tag}_{prof.name}_seed{prof.seed}.json")
                         .read_text())
        train_s, history = old["train_s"], old["history"]
        metrics = evaluate(model, crops.subset(crops.split == TEST))
    else:
        model.set_normalization(crops.patches, np.flatnonzero(crops.split == TRAIN))
        t0 = time.perf_counter()
        result = pooled.train_pooled(model, crops, prof.train, seed=prof.seed, progress=False)
        train_s, history, metrics = time.perf_counter() - t0, result.history, result.metrics
        torch.save(model.state_dict(), model_path)
    model.eval()
    dgt = load_checkpoint(data_dir(prof) / model_relpath("multitask")).model
    dgt_metrics = evaluate(dgt, ds.subset(ds.split == TEST))
    record = {"seed": prof.seed, "architecture": model.architecture(),
              "train": asdict(prof.train), "train_s": train_s, "history": history,
              "test": {"pooled": metrics, "dgt": dgt_metrics},
              "params": sum(p.numel() for p in model.parameters())}
    print(f"[seed {prof.seed}] trained in {train_s:.0f} s; test MSE "
          + ", ".join(f"{v} {metrics[v]['mse']:.4f} (DGTNet {dgt_metrics[v]['mse']:.4f})"
                      for v in metrics), flush=True)

    def dense(world, maps):
        t0, c0 = time.perf_counter(), time.process_time()
        cost = directional_costmap_dense(maps.bev, model, progress=False)
        return {"pooled": cost}, {"dense_s": time.perf_counter() - t0,
                                  "dense_cpu_s": time.process_time() - c0}

    record["accuracy"] = ground_truth_accuracy(prof, dense)
    return record


def report(records: list[dict]) -> str:
    """Markdown tables over the seeds' records: test MSE, ground-truth accuracy, times."""
    lines = [f"Seeds {[r['seed'] for r in records]}; {records[0]['architecture']}; "
             f"{records[0]['params']:,} parameters; trained "
             + ", ".join(f"{r['train_s']:.0f} s" for r in records) + ".", "",
             *test_lines(records, "pooled", "PooledNet"), "", *accuracy_lines(records), "",
             "Dense costmap (8 headings, 4 vehicles) wall / CPU [s]: "
             + "; ".join(f"{w} {a['shape'][0]}×{a['shape'][1]}: {a['dense_s']:.1f} / "
                         f"{a['dense_cpu_s']:.1f}"
                         for w, a in {a["world"]: a for a in records[0]["accuracy"]
                                      if "dense_s" in a}.items()),
             "load average at the end of each seed: "
             + "; ".join(" ".join(r["uptime"]) for r in records)]
    return "\n".join(lines) + "\n"


def main() -> None:
    study = Study("eval_pooled", __doc__, profile="demo", seeds=1, publishes=False)
    parser = study.parser
    parser.add_argument("--width", type=int, default=32)
    parser.add_argument("--depth", type=int, default=6)
    parser.add_argument("--fc-hidden", type=int, default=64)
    parser.add_argument("--reuse", action="store_true",
                        help="evaluate the networks a previous run saved, without training")
    parser.add_argument("--tag", default="", help="suffix of the output files (variants)")
    parser.add_argument("--report", action="store_true",
                        help="only print the tables of the saved results of the run seeds")
    args = study.parse()
    run_seeds(args, study.seeds, "pooled", run_seed, report)


if __name__ == "__main__":
    main()
