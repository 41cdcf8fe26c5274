"""Which training recipe gives models whose conclusions hold in every seed? Per recipe:

    .venv/bin/python studies/training_recipes.py --profile demo --seeds 3 --train-seeds 0 100 \\
        --recipes constant-best cosine-last --publish
    .venv/bin/python studies/training_recipes.py --profile paper --seed 0 \\
        --recipes cosine-last --epochs 8          # a shorter paper training budget

For every run seed (``--seeds N``: 0 … N-1, by default the profile's; or each ``--seed S``)
— its cached dataset, BEV maps, τ_s and ground truth: run ``dgt reproduce`` first — and every
training seed, trains the multi-task model and the four single-task models with each recipe
(a few ``TrainConfig`` fields changed from the profile's), then, without the closed loop:

1. collapse: each head's std(L̂) / std(L) on the test split (flagged below 0.1);
2. Experiment 1 and 2 plans: Hybrid A* on the DGT and single-task costmaps of the hill
   (carla_cola: which route up, which down) and the ridge (mercedes_van: where it crosses),
   for ``--queries`` queries each drawn as the experiments draw them;
3. accuracy against the ground truth (MAE and Spearman ρ of C = 1 − L̂ against the measured
   C*, on free cells) on the hill, ridge and eval worlds.

Training seed ``t`` seeds the weights and batch order only (the dataset is the run seed's),
so the spread over training seeds is what luck in the learning alone does. No model is
written to the cache; each evaluation's measurements are stored whole under
``<data>/studies/training_recipes/<profile>/`` as it finishes (a rerun resumes; ``--stored``
only prints), and ``--publish`` writes the table as a record that docs/training.md quotes.
"""

from __future__ import annotations

import json
import sys
import time
from collections import Counter

import numpy as np
from runner import Study, write_scores

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation import accuracy
from dgt_lib.evaluation.queries import classify_route, hill_queries, ridge_queries
from dgt_lib.learning.run import train_model
from dgt_lib.learning.training import COLLAPSE_RATIO, predict
from dgt_lib.mapping.costmap import directional_costmap
from dgt_lib.mapping.occupancy import occupancy_map
from dgt_lib.navigation.planner import HybridAStar
from dgt_lib.perception.dataset import PatchDataset
from dgt_lib.records.study import table
from dgt_lib.stages.costmaps import EXPERIMENT_VEHICLES, ensure_tau_s, world_bev
from dgt_lib.stages.dataset import DATASET_RELPATH
from dgt_lib.stages.ground_truth import GROUND_TRUTH_WORLDS, ensure_ground_truths
from dgt_lib.stages.paths import data_dir
from dgt_lib.world.terrain import get_world

RECIPES: dict[str, dict[str, object]] = {
    "constant-best": {"lr_schedule": "constant", "selection": "best_val", "patience": 5},
    "cosine-last": {"lr_schedule": "cosine", "selection": "last", "patience": None},
    "cosine-best": {"lr_schedule": "cosine", "selection": "best_val", "patience": None},
}
"""Recipe name → the TrainConfig fields it sets (the rest are the profile's). constant-best
is ``demo``'s recipe before the cosine schedule, cosine-last its recipe now."""


def _costmaps(models: dict, bev, prof) -> dict[tuple[str, str], np.ndarray]:
    """{(method, vehicle): (K, H, W)} of the multi-task (dgt) and single-task models."""
    k, kw = prof.costmap.n_headings, {"stride": prof.costmap.stride, "progress": False,
                                      "batch_size": prof.costmap.batch_size}
    multi = models["multitask"]
    cost = directional_costmap(bev, lambda p: predict(multi, p), k, **kw)
    out = {("dgt", v): cost[multi.head_index(v)] for v in multi.vehicles}
    for v in VEHICLES:
        single = models[f"single:{v}"]
        out[("single-task", v)] = directional_costmap(bev, lambda p, m=single: predict(m, p),
                                                      k, **kw)[0]
    return out


def _routes(world, queries, maps, occupancy, grid, vehicle, prof) -> dict[str, Counter]:
    """{method: Counter("label:route")} of the plans on each method's costmap."""
    out = {}
    for method in ("dgt", "single-task"):
        planner = HybridAStar.for_vehicle(maps[(method, vehicle)], occupancy, grid,
                                          get_vehicle(vehicle), prof.planner)
        counts = Counter()
        for q in queries:
            plan = planner.plan(q.start, q.goal)
            route = classify_route(world, plan.path) if plan.success else "no_path"
            counts[f"{q.label}:{route}"] += 1
        out[method] = counts
    return out


def evaluate_run(prof, recipe: dict, train_seed: int, n_queries: int, truths) -> dict:
    """Train the five models of one (run seed, training seed, recipe) and measure them."""
    ds = PatchDataset.from_arrays(artifacts.load(data_dir(prof) / DATASET_RELPATH))
    cfg = prof.train.__class__(**{**prof.train.__dict__, **recipe})
    t0 = time.perf_counter()
    models, collapse, epochs = {}, {}, {}
    for kind, vehicles in [("multitask", None)] + [(f"single:{v}", (v,)) for v in VEHICLES]:
        result = train_model(ds, cfg, vehicles=vehicles, seed=train_seed, progress=False)
        models[kind] = result.model
        epochs[kind] = result.best_epoch
        for v, m in result.metrics.items():
            collapse[f"{kind}/{v}"] = m["pred_std"] / max(m["label_std"], 1e-9)
    train_s = time.perf_counter() - t0
    tau_s = ensure_tau_s(prof)
    out = {"train_s": train_s, "epochs": epochs, "collapse": collapse, "routes": {},
           "accuracy": {}}
    for w in GROUND_TRUTH_WORLDS:
        world = get_world(w, prof)
        bev, _ = world_bev(w, prof, progress=False)
        occupancy = occupancy_map(bev, tau_s)
        maps = _costmaps(models, bev, prof)
        for v in EXPERIMENT_VEHICLES[w]:
            gt = truths[(w, v)]
            valid = gt.measured & accuracy.free_cells(occupancy, bev.grid, gt.cells)[:, None]
            for method in ("dgt", "single-task"):
                cost = accuracy.cost_at(maps[(method, v)], bev.grid, gt.cells,
                                        prof.costmap.n_headings)
                acc = accuracy.costmap_accuracy(gt.cost, cost, valid,
                                                prof.ground_truth.contrast_threshold)
                out["accuracy"][f"{w}/{v}/{method}"] = {"mae": acc["mae"],
                                                         "spearman": acc["spearman"]}
        ex = prof.experiments
        if w == "hill":
            qs = hill_queries(world, n_queries, ex, prof.seed)
            out["routes"]["hill"] = _routes(world, qs, maps, occupancy, bev.grid,
                                            "carla_cola", prof)
        elif w == "ridge":
            qs = ridge_queries(world, n_queries, ex, prof.seed)
            out["routes"]["ridge"] = _routes(world, qs, maps, occupancy, bev.grid,
                                             "mercedes_van", prof)
    return out


def _row(name: str, r: dict) -> list[object]:
    """One table row of a stored evaluation (:func:`evaluate_run` plus its names)."""
    head, worst = min(r["collapse"].items(), key=lambda kv: kv[1])
    kind, _, vehicle = head.partition("/")  # "multitask/jeep", "single:jeep/jeep"
    head = f"{'multi-task' if kind == 'multitask' else 'single-task'} {vehicle}"
    hill, ridge = r["routes"]["hill"]["dgt"], r["routes"]["ridge"]["dgt"]
    up = sum(c for k, c in hill.items() if k.startswith("ascent"))
    down = sum(c for k, c in hill.items() if k.startswith("descent"))
    ridge_n = sum(ridge.values())
    smooth = sum(c for k, c in ridge.items() if k.endswith(":smooth"))
    st_smooth = sum(c for k, c in r["routes"]["ridge"]["single-task"].items()
                    if k.endswith(":smooth"))
    mae = np.mean([a["mae"] for k, a in r["accuracy"].items() if k.endswith("/dgt")])
    collapsed = worst < COLLAPSE_RATIO
    holds = (not collapsed and hill.get("ascent:A", 0) == up
             and hill.get("descent:B", 0) == down and smooth == ridge_n)
    return [name, r["seed"], r["train_seed"],
            f"{worst:.2f} ({head}{', COLLAPSED' if collapsed else ''})",
            f"{hill.get('ascent:A', 0)}/{up}, {hill.get('descent:B', 0)}/{down}",
            f"{smooth}/{ridge_n}, {st_smooth}/{ridge_n}", f"{mae:.3f}",
            r["epochs"]["multitask"], "✓" if holds else "✗"]


def recipes_table(results: list[dict]) -> dict:
    """The study's table: one row per (recipe, run seed, training seed)."""
    return table("Training recipes without the closed loop",
                 ["recipe", "run seed", "training seed",
                  "lowest std(L̂) ÷ std(L) of the 8 heads", "DGT-Map hill: ascents by A, "
                  "descents by B", "ridge crossings at the smoothed section: DGT-Map, "
                  "DGT-Map(ST)", "DGT-Map ground-truth MAE (mean of 5 world–vehicle pairs)",
                  "multi-task epoch kept", "claims hold"],
                 [_row(r["recipe"], r) for r in results])


def main() -> None:
    study = Study("training_recipes", __doc__, profile="demo", seeds=None, stores=True)
    parser = study.parser
    parser.add_argument("--recipes", nargs="+", default=list(RECIPES), choices=list(RECIPES))
    parser.add_argument("--train-seeds", nargs="+", type=int, default=[0],
                        help="offsets added to the run seed for weights and batch order")
    parser.add_argument("--queries", type=int, default=12, help="hill and ridge queries each")
    parser.add_argument("--epochs", type=int, default=None,
                        help="epochs of every recipe (default: the profile's)")
    parser.add_argument("--width", type=int, default=None,
                        help="network width of every recipe (default: the profile's)")
    args = study.parse()
    prof = get_profile(args.profile)
    changed = {k: v for k, v in (("epochs", args.epochs), ("width", args.width))
               if v is not None}
    tag = "".join(f"_{k}{v}" for k, v in {**changed, "queries": args.queries}.items()
                  if k != "queries" or v != 12)  # the default query count keeps short names
    scores = artifacts.data_root() / "studies" / "training_recipes" / args.profile
    truths = None
    results = []
    for run in [prof.with_(seed=seed) for seed in study.seeds]:
        for t in args.train_seeds:
            for name in args.recipes:
                path = scores / f"{name}{tag}_seed{run.seed}_train{run.seed + t}.json"
                if not path.exists():
                    if args.stored:
                        continue
                    truths = truths or ensure_ground_truths(None, prof, progress=False)
                    r = evaluate_run(run, {**RECIPES[name], **changed}, run.seed + t,
                                     args.queries, truths)
                    r["routes"] = {w: {m: dict(c) for m, c in d.items()}
                                   for w, d in r["routes"].items()}
                    write_scores(path, {"recipe": name, "seed": run.seed,
                                        "train_seed": run.seed + t, **r})
                    print(f"[training_recipes] {name} seed {run.seed} train {run.seed + t}: "
                          f"{r['train_s']:.0f} s of training", flush=True)
                results.append(json.loads(path.read_text()))
    if not results:
        print(f"no stored evaluations under {scores}: run without --stored first",
              file=sys.stderr)
        raise SystemExit(2)
    study.finish({"recipes": recipes_table(results)},
                 seeds=sorted({r["seed"] for r in results}), variant=tag.strip("_"))


if __name__ == "__main__":
    main()
