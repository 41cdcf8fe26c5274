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

Nothing of the profile is rebuilt (it stops if an artifact is not cached fresh). Each
seed's results go to ``data/pooled/``; ``--stored`` prints (and ``--publish`` publishes)
the tables from those alone, ``--tag _d4`` keeps a variant's files and record apart, and
``--sizes _d4 …`` adds a table of those stored sizes' errors beside the record's own.

    DGT_DATA_DIR=... python studies/eval_pooled.py --profile demo --seeds 3 --publish
    DGT_DATA_DIR=... python studies/eval_pooled.py --profile demo --seeds 3 --depth 4 --tag _d4
    DGT_DATA_DIR=... python studies/eval_pooled.py --profile demo --seeds 3 --stored \
        --sizes _d4 --publish
"""

from __future__ import annotations

import argparse
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
from dgt_lib.records.study import table  # noqa: E402
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


def _percent(share: float | None) -> str:
    """A share as whole percent; "—" where it is undefined (no cell of the world has a
    harder direction in the truth)."""
    return "—" if share is None or not np.isfinite(share) else f"{100 * share:.0f}"


def _test_table(records: list[dict]) -> dict:
    """Test MSE per seed and mean Spearman ρ per vehicle, PooledNet beside DGTNet."""
    rows = []
    for v in VEHICLES:
        c = [r["test"]["pooled"][v] for r in records if v in r["test"]["pooled"]]
        d = [r["test"]["dgt"][v] for r in records if v in r["test"]["dgt"]]
        rows.append([v, ", ".join(f"{m['mse']:.4f}" for m in c),
                     ", ".join(f"{m['mse']:.4f}" for m in d),
                     f"{_mean(m['spearman'] for m in c):.2f}",
                     f"{_mean(m['spearman'] for m in d):.2f}"])
    return table("The test split: MSE of L̂ seed by seed, Spearman ρ mean over the seeds",
                 ["vehicle", "test MSE, PooledNet", "test MSE, DGTNet", "ρ, PooledNet",
                  "ρ, DGTNet"], rows)


def _accuracy_table(records: list[dict]) -> dict:
    """Per world and vehicle: each network's MAE against the measured ground truth (means
    over the seeds) and in how many seeds PooledNet's is the lower."""
    pairs = list(dict.fromkeys((a["world"], a["vehicle"]) for a in records[0]["accuracy"]))
    rows = []
    for w, v in pairs:
        mae = [{a["method"]: a["mae"] for a in r["accuracy"] if (a["world"], a["vehicle"])
                == (w, v)} for r in records]
        rho = {m: _mean(a["spearman"] for r in records for a in r["accuracy"]
                        if (a["world"], a["vehicle"], a["method"]) == (w, v, m))
               for m in ("dgt", "pooled")}
        sign = {m: " / ".join(_percent(a["sign_agreement"]) for r in records
                              for a in r["accuracy"]
                              if (a["world"], a["vehicle"], a["method"]) == (w, v, m))
                for m in ("dgt", "pooled")}
        lower = sum(m["pooled"] < m["dgt"] for m in mae)
        rows.append([f"{w}, {v}", f"{_mean(m['dgt'] for m in mae):.3f}",
                     f"{_mean(m['pooled'] for m in mae):.3f}", f"{lower} of {len(mae)}",
                     f"{rho['dgt']:.2f}", f"{rho['pooled']:.2f}",
                     f"{sign['dgt']} · {sign['pooled']} (%)"])
    return table("Against the measured ground truth (lower MAE is closer), means over the "
                 "seeds", ["world, vehicle", "MAE, DGT-Map (DGTNet)", "MAE, PooledNet (dense)",
                           "seeds where PooledNet's is lower", "ρ, DGTNet", "ρ, PooledNet",
                           "harder direction on the right side, seed by seed: DGTNet · "
                           "PooledNet"], rows)


def _times_table(records: list[dict]) -> dict:
    """Each seed's training time and its dense costmaps' wall / CPU time per world, with
    the load average when the seed ended."""
    worlds = [a["world"] for a in {a["world"]: a for a in records[0]["accuracy"]
                                   if "dense_s" in a}.values()]
    rows = []
    for r in records:
        dense = {a["world"]: a for a in r["accuracy"] if "dense_s" in a}
        rows.append([r["seed"], f"{r['params']:,}", f"{r['train_s']:.0f}",
                     *(f"{dense[w]['dense_s']:.1f} / {dense[w]['dense_cpu_s']:.1f}"
                       for w in worlds), " ".join(r["uptime"])])
    a = records[0]["architecture"]
    return table(f"Time [s]: training, then the dense costmap (8 headings, 4 vehicles) per "
                 f"world, wall / CPU; PooledNet width {a['width']}, depth {a['depth']}, fully "
                 f"connected {a['fc_hidden']}",
                 ["seed", "parameters", "training", *(f"{w} dense" for w in worlds),
                  "load at the end"], rows)


def _sizes_table(variants: list[list[dict]]) -> dict:
    """Each network size's MAE against the measured ground truth per world and vehicle
    (means over the seeds), DGTNet's first, and in how many vehicle-seeds its test MSE is
    below DGTNet's; ``variants``: each size's seed records, smallest first."""
    def label(records):
        a = records[0]["architecture"]
        return f"width {a['width']}, depth {a['depth']}"

    def mae(records, w, v, method):
        return _mean(a["mae"] for r in records for a in r["accuracy"]
                     if (a["world"], a["vehicle"], a["method"]) == (w, v, method))

    def below(records):
        pairs = [(r["test"]["pooled"][v]["mse"], r["test"]["dgt"][v]["mse"])
                 for r in records for v in r["test"]["pooled"]]
        return f"{sum(c < d for c, d in pairs)} of {len(pairs)} vehicle-seeds"

    first = variants[0]
    pairs = list(dict.fromkeys((a["world"], a["vehicle"]) for a in first[0]["accuracy"]))
    rows = [[f"{w}, {v}", f"{mae(first, w, v, 'dgt'):.3f}",
             *(f"{mae(rs, w, v, 'pooled'):.3f}" for rs in variants)] for w, v in pairs]
    rows.append(["test MSE below DGTNet's", "—", *(below(rs) for rs in variants)])
    return table("MAE against the measured ground truth by PooledNet's size, means over the "
                 "seeds", ["world, vehicle", "DGT-Map (DGTNet)",
                           *(f"PooledNet {label(rs)}" for rs in variants)], rows)


def main() -> None:
    study = Study("eval_pooled", __doc__, profile="demo", seeds=1, stores=True)
    parser = study.parser
    parser.add_argument("--width", type=int, default=32)
    parser.add_argument("--depth", type=int, default=6)
    parser.add_argument("--fc-hidden", type=int, default=64)
    parser.add_argument("--reuse", action="store_true",
                        help="evaluate the networks a previous run saved, without training")
    parser.add_argument("--tag", default="", help="suffix of the output files and the "
                                                  "record (variants, e.g. _d4)")
    parser.add_argument("--sizes", nargs="+", default=[], metavar="TAG",
                        help="the stored variants (run before with --tag) to set beside this "
                             "one in a table by size (e.g. _d4 _d8)")
    args = study.parse()
    records = run_seeds(args, study.seeds, "pooled", run_seed)
    tables = {"test": _test_table(records), "accuracy": _accuracy_table(records),
              "times": _times_table(records)}
    if args.sizes:
        variants = [records] + [run_seeds(argparse.Namespace(**{**vars(args), "stored": True,
                                                                 "tag": t}),
                                          study.seeds, "pooled", run_seed) for t in args.sizes]
        variants.sort(key=lambda rs: (rs[0]["architecture"]["width"],
                                      rs[0]["architecture"]["depth"]))
        tables["sizes"] = _sizes_table(variants)
    study.finish(tables, variant=args.tag.strip("_"))


def run_seeds(args, seeds: list[int], subdir: str, run_seed) -> list[dict]:
    """The seeds loop of an evaluation script: each seed's ``run_seed(profile, args)``
    record (with the load average) is saved under ``data/<subdir>/`` (only reading the
    profile's cache), a seed already saved there is not run again; with ``--stored`` the
    saved records of run seeds ``seeds`` are read instead. Returns the seeds' records."""
    out_dir = artifacts.data_root() / subdir
    paths = [out_dir / f"results{args.tag}_{args.profile}_seed{s}.json" for s in seeds]
    if not args.stored:
        artifacts.ensure = _load_only
        torch.set_num_threads(int(os.environ.get("OMP_NUM_THREADS", "2")))
        base = as_profile(args.profile)
        for seed, path in zip(seeds, paths, strict=True):
            if path.exists() and not args.reuse:  # a rerun resumes after the stored seeds
                print(f"[seed {seed}] stored: {path}", flush=True)
                continue
            record = run_seed(base.with_(seed=seed), args)
            record["uptime"] = open("/proc/loadavg").read().split()[:3]
            path.write_text(json.dumps(record, indent=1))
            print(f"wrote {path}", flush=True)
    missing = [str(path) for path in paths if not path.exists()]
    if missing:
        raise SystemExit(f"not stored: {', '.join(missing)} (run the seeds first"
                         + (f", with --tag {args.tag})" if args.tag else ")"))
    return [json.loads(path.read_text()) for path in paths]


if __name__ == "__main__":
    main()
