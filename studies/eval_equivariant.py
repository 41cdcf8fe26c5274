"""The C8-equivariant network against DGT-Map's multi-task DGTNet, on a profile's cached data.

For each run seed: train :class:`~dgt_lib.beyond.equivariant.C8Net` on the seed's dataset
and training-world BEV (the dataset's own train/val/test split), then report

- test MSE / Spearman ρ per vehicle beside the seed's cached multi-task DGTNet (same test
  samples; the C8Net reads each pose's exact heading: crop rotated to bin 0, channel 0);
- the equivariance error on the eval world: |L̂(map rotated by k·45°)_j+k − L̂(map)_j| at
  the centres of 512 random observed cells, k = 1 (45°) and k = 2 (90°);
- the accuracy against the measured ground truth on hill / ridge / eval (the scoring of
  ``stages.ground_truth.score_world``: MAE, Spearman ρ, directional contrast), beside the
  cached DGT-Map costmaps; and the one-pass costmap time of each world.

Nothing of the profile is rebuilt: every cached artifact must be fresh, or the script stops
(it never writes under ``data/<profile>/``). Results go to ``data/equivariant/``.

    DGT_DATA_DIR=... python studies/eval_equivariant.py --profile demo --seeds 3
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

from dgt_lib.beyond import equivariant as eq  # noqa: E402
from dgt_lib.core import artifacts  # noqa: E402
from dgt_lib.core.config import VEHICLES, as_profile  # noqa: E402
from dgt_lib.evaluation import accuracy  # noqa: E402
from dgt_lib.learning.checkpoints import load_checkpoint  # noqa: E402
from dgt_lib.learning.training import evaluate  # noqa: E402
from dgt_lib.perception.dataset import TEST  # noqa: E402
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
    cfg = eq.EquivariantConfig(fields=args.fields, depth=args.depth, epochs=args.epochs,
                               rgb=not args.no_rgb)
    out_dir = artifacts.data_root() / "equivariant"
    out_dir.mkdir(parents=True, exist_ok=True)
    model_path = out_dir / f"c8net{args.tag}_{prof.name}_seed{prof.seed}.pt"
    previous = out_dir / f"results{args.tag}_{prof.name}_seed{prof.seed}.json"
    if args.reuse:  # the trained network and its training record, evaluated again
        result = eq.EquivariantResult.from_dict(torch.load(model_path, weights_only=False))
        old = json.loads(previous.read_text())
        train_s, train_cpu = old["train_s"], old["train_cpu_s"]
    else:
        t0, c0 = time.perf_counter(), time.process_time()
        result = eq.train_equivariant(ds, bev, cfg, seed=prof.seed)
        train_s, train_cpu = time.perf_counter() - t0, time.process_time() - c0
        torch.save(result.to_dict(), model_path)
    dgt = load_checkpoint(data_dir(prof) / model_relpath("multitask")).model
    dgt_metrics = evaluate(dgt, ds.subset(ds.split == TEST))
    record = {"seed": prof.seed, "config": asdict(result.config), "train_s": train_s,
              "train_cpu_s": train_cpu, "history": result.history,
              "best_epoch": result.best_epoch, "test": {"c8net": result.metrics,
                                                        "dgt": dgt_metrics},
              "params": sum(p.numel() for p in result.model.parameters())}
    print(f"[seed {prof.seed}] trained in {train_s:.0f} s; test MSE "
          + ", ".join(f"{v} {result.metrics[v]['mse']:.4f} (DGTNet {dgt_metrics[v]['mse']:.4f})"
                      for v in result.metrics), flush=True)

    def one_pass(world, maps):
        t0, c0 = time.perf_counter(), time.process_time()
        point = eq.equivariant_costmap(maps.bev, result.model, average=False)  # (V, 8, H, W)
        secs, cpu = time.perf_counter() - t0, time.process_time() - c0
        t0 = time.perf_counter()
        cost = eq.equivariant_costmap(maps.bev, result.model)  # footprint-averaged
        secs_avg = time.perf_counter() - t0
        if world == "eval":
            record["equivariance"] = eq.equivariance_error(result.model, maps.bev)
        return ({"c8net": cost, "c8net-point": point},
                {"onepass_s": secs, "onepass_cpu_s": cpu, "averaged_s": secs_avg})

    rows = ground_truth_accuracy(prof, one_pass)
    record["accuracy"] = rows
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
    """Markdown tables over the seeds' records: test MSE, ground-truth accuracy,
    equivariance error, training and one-pass times."""
    seeds = [r["seed"] for r in records]
    lines = [f"Seeds {seeds}; {records[0]['params']:,} parameters; trained "
             + ", ".join(f"{r['train_s']:.0f} s" for r in records)
             + f" (best epochs {[r['best_epoch'] for r in records]}).", "",
             *test_lines(records, "c8net", "C8Net")]
    lines += ["", *accuracy_lines(records)]
    lines += ["", "| seed | 90°: mean / max abs ΔL̂ | 45°: mean / max abs ΔL̂ |", "|---|---|---|"]
    for r in records:
        e = r["equivariance"]
        lines.append(f"| {r['seed']} | {e['mean_90']:.1e} / {e['max_90']:.1e} | "
                     f"{e['mean_45']:.4f} / {e['max_45']:.3f} |")
    lines += ["", "One pass (all 8 headings, 4 vehicles; point / footprint-averaged) [s]: "
              + "; ".join(f"{w} {a['shape'][0]}×{a['shape'][1]}: {a['onepass_s']:.1f} / "
                          f"{a['averaged_s']:.1f}"
                          for w, a in {a["world"]: a for a in records[0]["accuracy"]}.items()
                          if "averaged_s" in a),
              "load average at the end of each seed: "
              + "; ".join(" ".join(r["uptime"]) for r in records)]
    return "\n".join(lines) + "\n"


def main() -> None:
    study = Study("eval_equivariant", __doc__, profile="demo", seeds=1, publishes=False)
    parser = study.parser
    parser.add_argument("--fields", type=int, default=8)
    parser.add_argument("--depth", type=int, default=4)
    parser.add_argument("--epochs", type=int, default=10)
    parser.add_argument("--reuse", action="store_true",
                        help="evaluate the networks a previous run saved, without training")
    parser.add_argument("--tag", default="", help="suffix of the output files (variants)")
    parser.add_argument("--no-rgb", action="store_true", help="ablation: colour zeroed")
    parser.add_argument("--report", action="store_true",
                        help="only print the tables of the saved results of the run seeds")
    args = study.parse()
    run_seeds(args, study.seeds, "equivariant", run_seed, report)


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
