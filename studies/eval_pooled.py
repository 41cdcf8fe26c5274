"""The densely evaluable PooledNet against DGT-Map's multi-task DGTNet, on a profile's cached data.

For each run seed: train :class:`~dgt_lib.beyond.pooled.PooledNet` with the profile's own
training recipe (``profile.train``: epochs, batch size, learning rate, schedule, selection,
mirror augmentation) through :func:`~dgt_lib.beyond.pooled.train_pooled`, on the seed's
dataset with each patch re-cut with its context margin from the training world's BEV (same
poses, labels and train/val/test split); then report

- test MSE / Spearman ρ per vehicle beside the seed's cached multi-task DGTNet;
- the accuracy against the measured ground truth on hill / ridge / eval (MAE, Spearman ρ,
  directional contrast) beside the cached DGT-Map costmaps, the PooledNet's costmaps made
  by dense evaluation;
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
from runner import Study  # noqa: E402

from dgt_lib.beyond import pooled  # noqa: E402
from dgt_lib.beyond.dense import directional_costmap_dense  # noqa: E402
from dgt_lib.core import artifacts  # noqa: E402
from dgt_lib.core.config import VEHICLES, as_profile  # noqa: E402
from dgt_lib.evaluation import accuracy  # noqa: E402
from dgt_lib.learning.checkpoints import load_checkpoint  # noqa: E402
from dgt_lib.learning.training import evaluate  # noqa: E402
from dgt_lib.perception.dataset import TEST, TRAIN  # noqa: E402
from dgt_lib.stages.collect import ensure_bev  # noqa: E402
from dgt_lib.stages.costmaps import EXPERIMENT_VEHICLES, ensure_world_costmaps  # noqa: E402
from dgt_lib.stages.dataset import ensure_dataset  # noqa: E402
from dgt_lib.stages.ground_truth import (  # noqa: E402
    GROUND_TRUTH_WORLDS,
    ensure_ground_truths,
    ground_truth_config,
    ground_truth_pairs,
    ground_truth_relpath,
)
from dgt_lib.stages.paths import data_dir  # noqa: E402
from dgt_lib.stages.train import model_relpath  # noqa: E402

_ensure = artifacts.ensure


def _load_only(relpath, config, build, *, profile, **kwargs):
    """``artifacts.ensure`` that refuses to build: this script only reads the cache."""
    why = artifacts.staleness(relpath, config, profile=profile)
    if why is not None:
        raise RuntimeError(f"{profile}/{relpath} is not cached fresh ({why}): build it first")
    return _ensure(relpath, config, build, profile=profile, **kwargs)


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


def ground_truth_accuracy(prof, costmaps) -> list[dict]:
    """Rows of :func:`~dgt_lib.evaluation.accuracy.costmap_accuracy` against the cached
    ground truths of hill / ridge / eval for the cached DGT-Map costmaps and the methods of
    ``costmaps(world, maps)`` → ({method: cost (len(VEHICLES), 8, H, W)}, extra fields of
    the world's rows). Stops when a ground truth is not cached (never drives)."""
    for w, v in ground_truth_pairs():
        if not artifacts.is_fresh(ground_truth_relpath(w, v), ground_truth_config(w, v, prof),
                                  profile=prof.name):
            raise RuntimeError(f"the ground truth of {v} on {w} is not cached fresh")
    truths = ensure_ground_truths(None, prof, progress=False)
    rows = []
    for world in GROUND_TRUTH_WORLDS:
        vehicles = EXPERIMENT_VEHICLES[world]
        maps = ensure_world_costmaps(world, vehicles, prof, methods=("dgt",), progress=False)
        methods, extra = costmaps(world, maps)
        for v in vehicles:
            gt = truths[(world, v)]
            valid = gt.measured & accuracy.free_cells(maps.occupancy, maps.grid, gt.cells)[:, None]
            layers = {"dgt": maps.costmap("dgt", v),
                      **{m: cost[VEHICLES.index(v)] for m, cost in methods.items()}}
            for method, layer in layers.items():
                c = accuracy.cost_at(layer, maps.grid, gt.cells, gt.cost.shape[1])
                rows.append({"world": world, "vehicle": v, "method": method,
                             "shape": list(maps.grid.shape), **extra,
                             **accuracy.costmap_accuracy(gt.cost, c, valid)})
    return rows


def _mean(values) -> float:
    values = [v for v in values if v is not None and np.isfinite(v)]
    return float(np.mean(values)) if values else float("nan")


def test_lines(records: list[dict], key: str, name: str) -> list[str]:
    """A markdown table of test MSE per seed and mean Spearman ρ per vehicle, the network
    ``records[i]["test"][key]`` beside DGTNet (``["dgt"]``)."""
    lines = [f"| vehicle | test MSE {name} (seeds) | test MSE DGTNet (seeds) | ρ {name} | "
             "ρ DGTNet |", "|---|---|---|---|---|"]
    for v in VEHICLES:
        c = [r["test"][key][v] for r in records if v in r["test"][key]]
        d = [r["test"]["dgt"][v] for r in records if v in r["test"]["dgt"]]
        mse_c = ", ".join(f"{m['mse']:.4f}" for m in c)
        mse_d = ", ".join(f"{m['mse']:.4f}" for m in d)
        lines.append(f"| {v} | {mse_c} | {mse_d} | {_mean(m['spearman'] for m in c):.2f} | "
                     f"{_mean(m['spearman'] for m in d):.2f} |")
    return lines


def accuracy_lines(records: list[dict]) -> list[str]:
    """A markdown table of the seeds' ground-truth accuracy rows, means over the seeds."""
    lines = ["| world, vehicle | method | MAE (mean over seeds) | ρ | contrast: truth / "
             "method | same sign |", "|---|---|---|---|---|---|"]
    keys = list(dict.fromkeys((a["world"], a["vehicle"], a["method"])
                              for a in records[0]["accuracy"]))
    for w, v, m in keys:
        rows = [a for r in records for a in r["accuracy"]
                if (a["world"], a["vehicle"], a["method"]) == (w, v, m)]
        lines.append(f"| {w}, {v} | {m} | {_mean(a['mae'] for a in rows):.3f} | "
                     f"{_mean(a['spearman'] for a in rows):.2f} | "
                     f"{_mean(a['contrast_true'] for a in rows):.2f} / "
                     f"{_mean(a['contrast'] for a in rows):.2f} | "
                     f"{100 * _mean(a['sign_agreement'] for a in rows):.0f} % |")
    return lines


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


def run_seeds(args, seeds: list[int], subdir: str, run_seed, report) -> None:
    """The seeds loop of an evaluation script: ``--report`` prints ``report`` of the saved
    records of run seeds ``seeds``; otherwise each seed's ``run_seed(profile, args)`` record
    (with the load average) is saved under ``data/<subdir>/`` (only reading the profile's
    cache) and the report of all of them printed at the end."""
    out_dir = artifacts.data_root() / subdir
    paths = [out_dir / f"results{args.tag}_{args.profile}_seed{s}.json" for s in seeds]
    if not args.report:
        artifacts.ensure = _load_only
        torch.set_num_threads(int(os.environ.get("OMP_NUM_THREADS", "2")))
        base = as_profile(args.profile)
        for seed, path in zip(seeds, paths, strict=True):
            record = run_seed(base.with_(seed=seed), args)
            record["uptime"] = open("/proc/loadavg").read().split()[:3]
            path.write_text(json.dumps(record, indent=1))
            print(f"wrote {path}", flush=True)
    print(report([json.loads(path.read_text()) for path in paths]))


if __name__ == "__main__":
    main()
