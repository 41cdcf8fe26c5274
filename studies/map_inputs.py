"""What does the network look at, and what does a noisy localisation cost? Per variant and
run seed, the multi-task model's accuracy against the measured ground truth and its plans
in Experiments 1 and 2.

    .venv/bin/python studies/map_inputs.py --profile demo --seeds 3 \\
        --variants rgbd geometry rgb shuffled            # input attribution
    .venv/bin/python studies/map_inputs.py --profile demo --seeds 3 \\
        --variants rgbd pose_low pose_mid pose_high      # pose noise
    .venv/bin/python studies/map_inputs.py --profile demo --seeds 3 \\
        --variants rgbd geometry rgb shuffled --stored --publish

Variants (:data:`VARIANTS`, each a set of ``--set`` settings, fixed before any was run):
``rgbd`` the paper (every channel, true poses); ``geometry`` / ``rgb`` the network sees only
H̄, σ_H, ‖∇H̄‖ / only the colours; ``shuffled`` every world's colour layer tile-permuted, so
rock colour cannot mark steep or sharp ground; ``pose_*`` the frames of the training
data and of the evaluation maps placed with per-frame position and heading noise and a
drifting bias (``BEVConfig``).

Each variant runs in its own data directory ``<out>/<variant>/`` (``rgbd``: the profile's
own, ``$DGT_DATA_DIR`` or ``data/``). Variants that keep the poses share the profile's
collection episodes and every variant its ground truth (symbolic links), so only what
differs is built: the BEV maps, dataset, multi-task model, its costmaps. Everything is
cached and resumable like the pipeline's stages. Per (variant, seed) the script stores
``<out>/scores/<variant>_seed<S>.json``: MAE, Spearman ρ and directional contrast per
(world, vehicle) of the ``dgt`` costmap, the routes of its plans for Experiment 1's
(carla_cola, hill) and Experiment 2's (mercedes_van, ridge) queries — the paper's counts, 20
and 50, planned only, not driven — and each head's cost at the ridge's two crossings. Then it
prints the tables over seeds and draws ``<out>/map_inputs.png``. ``--stored``: tables and
figure from the stored scores only.

The tables (:func:`tables`): ``mae`` (MAE per variant and (world, vehicle), mean ± std over
seeds) and ``plans`` (the plan claims per seed, and the van's cost at the two crossings).
``--publish`` writes them to
``docs/runs/studies/map_inputs-<variant>_<profile>_<processor>_<date>.json``; publish a run
once its scores are stored, with ``--stored --publish`` and the same ``--variants``. The
record's variant is ``attribution`` for variants among rgbd, geometry, rgb and shuffled,
``pose`` for variants among rgbd and ``pose_*``, else the variants' names ``-``-joined, so
the two studies' records never overwrite each other.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from planned import CLAIMS, PLANNED, planned_routes, planning_profile
from planned import claim_share as _share
from runner import Study, link, stored_or_run, write_scores

from dgt_lib.records.study import table

VARIANTS: dict[str, dict[str, object]] = {
    "rgbd": {},
    "geometry": {"train.inputs": "geometry"},
    "rgb": {"train.inputs": "rgb"},
    "shuffled": {"bev.colour": "shuffled"},
    "pose_low": {"bev.pose_sigma_xy_m": 0.1, "bev.pose_sigma_yaw_deg": 0.5,
                 "bev.pose_drift_m": 0.01},
    "pose_mid": {"bev.pose_sigma_xy_m": 0.3, "bev.pose_sigma_yaw_deg": 2.0,
                 "bev.pose_drift_m": 0.02},
    "pose_high": {"bev.pose_sigma_xy_m": 1.0, "bev.pose_sigma_yaw_deg": 2.0,
                  "bev.pose_drift_m": 0.05},
}
"""Each variant's settings (``dgt reproduce --set`` names)."""

RIDGE_LANDMARKS = ("sharp_crossing", "smooth_crossing")
NORTH = 2  # heading layer θ = π/2 of K = 8: across the ridge


def variant_root(variant: str, base: Path, out: Path) -> Path:
    """The data directory a variant's artifacts go to."""
    return base if not VARIANTS[variant] else out / variant


def prepare(variant: str, profile: str, seed: int, base: Path, out: Path) -> Path:
    """The variant's data directory, with the links to what it shares with the base run."""
    root = variant_root(variant, base, out)
    if root == base:
        return root
    link(base / profile / "ground_truth", root / profile / "ground_truth")
    if not any(k.startswith("bev.pose") for k in VARIANTS[variant]):
        link(base / profile / f"seed-{seed}" / "episodes",
              root / profile / f"seed-{seed}" / "episodes")
    return root


def _ridge_costs(prof) -> dict[str, dict[str, float]]:
    """Each ridge head's mean cost heading north over 5 × 5 cells at the two crossings."""
    from dgt_lib.stages.experiments import trial_maps
    from dgt_lib.world.terrain import get_world

    ridge = get_world("ridge", prof)
    out = {}
    for v in ("jeep", "mercedes_van"):
        maps = trial_maps("ridge", "dgt", v, prof)
        cost = maps.costmap("dgt", v)
        out[v] = {}
        for key in RIDGE_LANDMARKS:
            r, c = maps.grid.xy_to_cell(*ridge.landmarks[key])
            out[v][key] = float(cost[NORTH, r - 2:r + 3, c - 2:c + 3].mean())
    return out


def score(variant: str, profile: str, seed: int) -> dict:
    """Build (through the cache) and score one variant in one seed; runs in the variant's
    own process (its ``DGT_DATA_DIR``)."""
    from dgt_lib.core.config import get_profile
    from dgt_lib.stages.costmaps import EXPERIMENT_VEHICLES
    from dgt_lib.stages.ground_truth import GROUND_TRUTH_WORLDS, ensure_ground_truths, score_world

    prof = get_profile(profile).with_(seed=seed)
    if VARIANTS[variant]:
        prof = prof.with_overrides(VARIANTS[variant])
    plan_prof = planning_profile(prof)
    pairs = [(w, v) for w in GROUND_TRUTH_WORLDS for v in EXPERIMENT_VEHICLES[w]]
    truths = ensure_ground_truths(pairs, prof)
    rows = []
    for w in GROUND_TRUTH_WORLDS:
        rows += score_world(w, truths, prof, methods=("dgt",))[0]
    return {"variant": variant, "seed": seed, "settings": VARIANTS[variant],
            "accuracy": [{k: r[k] for k in ("world", "vehicle", "mae", "spearman", "contrast")}
                         for r in rows],
            "plans": {name: planned_routes(name, plan_prof) for name in PLANNED},
            "ridge_costs": _ridge_costs(prof)}


def run_one(variant: str, profile: str, seed: int, base: Path, out: Path) -> dict:
    """The stored scores of (variant, seed), computed in a subprocess if missing."""
    path = out / "scores" / f"{variant}_seed{seed}.json"
    if path.exists():
        return json.loads(path.read_text())
    root = prepare(variant, profile, seed, base, out)
    return stored_or_run(path, root, [__file__, "--one", variant, str(seed), "--profile",
                                      profile, "--out", str(out)], f"{variant} seed {seed}")


ATTRIBUTION = ("rgbd", "geometry", "rgb", "shuffled")
"""The input attribution's variants."""
POSE = ("rgbd", "pose_low", "pose_mid", "pose_high")
"""The pose-noise variants, beside the paper's true poses."""
LABELS = {"shuffled": "shuffled colours", "geometry": "geometry only", "rgb": "RGB only"}
"""The tables' names of the attribution's variants."""


def row_label(variant: str, pose_run: bool) -> str:
    """A variant's row in the tables: ``rgbd`` is the paper ("true poses" beside pose
    noise), a pose variant its noise levels, the others :data:`LABELS`."""
    if variant == "rgbd":
        return "true poses (the paper)" if pose_run else "rgbd (the paper)"
    cfg = VARIANTS[variant]
    if "bev.pose_sigma_xy_m" in cfg:
        xy = cfg["bev.pose_sigma_xy_m"]
        return (f"σ_xy {xy:.1f} m" if round(xy, 1) == xy else f"σ_xy {xy:g} m") + (
            f", σ_ψ {cfg['bev.pose_sigma_yaw_deg']:g}°, σ_d {cfg['bev.pose_drift_m']:g} m")
    return LABELS.get(variant, variant)


def mae_table(scores: list[dict]) -> dict:
    """MAE per (world, vehicle) and variant, mean ± std over seeds; the last column the
    mean over every pair and seed."""
    variants = list(dict.fromkeys(s["variant"] for s in scores))
    pose_run = any(v in POSE[1:] for v in variants)
    pairs = list(dict.fromkeys((r["world"], r["vehicle"]) for r in scores[0]["accuracy"]))
    rows = []
    for var in variants:
        mine = sorted((s for s in scores if s["variant"] == var), key=lambda s: s["seed"])
        per_pair = [[next(r["mae"] for r in s["accuracy"] if (r["world"], r["vehicle"]) == p)
                     for s in mine] for p in pairs]
        rows.append([row_label(var, pose_run), ", ".join(str(s["seed"]) for s in mine),
                     *(f"{np.mean(x):.3f} ± {np.std(x):.3f}" for x in per_pair),
                     f"{np.mean(per_pair):.3f}"])
    return table("MAE of the dgt costmap against the measured ground truth (mean ± std over "
                 "the seeds)", ["variant", "seeds", *(f"{w} {v}" for w, v in pairs), "mean"],
                 rows)


def plan_table(scores: list[dict]) -> dict:
    """The plan claims per variant, one count per seed, and the mercedes_van head's cost
    heading north at the ridge's sharp and smoothed crossings."""
    variants = list(dict.fromkeys(s["variant"] for s in scores))
    pose_run = any(v in POSE[1:] for v in variants)
    rows = []
    for var in variants:
        mine = sorted((s for s in scores if s["variant"] == var), key=lambda s: s["seed"])
        cols = [", ".join("{}/{}".format(*_share(s["plans"][exp], label, route)) for s in mine)
                for exp, label, route in CLAIMS]
        costs = ", ".join(f"{s['ridge_costs']['mercedes_van']['sharp_crossing']:.2f} / "
                          f"{s['ridge_costs']['mercedes_van']['smooth_crossing']:.2f}"
                          for s in mine)
        rows.append([row_label(var, pose_run), *cols, costs])
    return table("Plans of Experiments 1–2 (planned, not driven; one count per seed) and the "
                 "mercedes_van head's cost heading north at the ridge's two crossings",
                 ["variant", "hill ascents by Route A", "hill descents by Route B",
                  "ridge crossings at the smoothed section", "van cost sharp / smooth (N)"],
                 rows)


def tables(scores: list[dict]) -> dict[str, dict]:
    """The study's tables (:func:`~dgt_lib.records.study.table`): ``mae`` and ``plans``."""
    return {"mae": mae_table(scores), "plans": plan_table(scores)}


def record_variant(scores: list[dict]) -> str:
    """The record's variant: ``attribution`` for exactly the variants of :data:`ATTRIBUTION`,
    ``pose`` for exactly those of :data:`POSE`, otherwise the variants' names ``-``-joined
    (in :data:`VARIANTS` order), so the two studies' records never overwrite each other and
    a partial run never overwrites a whole one."""
    ran = {s["variant"] for s in scores}
    if ran == set(ATTRIBUTION):
        return "attribution"
    if ran == set(POSE):
        return "pose"
    return "-".join(v for v in VARIANTS if v in ran)


def tick_label(variant: str) -> str:
    """A variant's name, with its noise levels for the pose variants."""
    cfg = VARIANTS[variant]
    if "bev.pose_sigma_xy_m" not in cfg:
        return variant
    return (f"σ_xy {cfg['bev.pose_sigma_xy_m']:g} m\nσ_ψ {cfg['bev.pose_sigma_yaw_deg']:g}°\n"
            f"σ_d {cfg['bev.pose_drift_m']:g} m")


def figure(scores: list[dict], path: Path) -> None:
    """MAE per variant (mean over pairs, each seed a dot) and the ridge plans' share at the
    smoothed section."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    variants = list(dict.fromkeys(s["variant"] for s in scores))
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), constrained_layout=True)
    for i, var in enumerate(variants):
        mine = [s for s in scores if s["variant"] == var]
        mae = [np.mean([r["mae"] for r in s["accuracy"]]) for s in mine]
        smooth = [np.divide(*_share(s["plans"]["experiment2"], None, "smooth")) for s in mine]
        ascent = [np.divide(*_share(s["plans"]["experiment1"], "ascent", "A")) for s in mine]
        descent = [np.divide(*_share(s["plans"]["experiment1"], "descent", "B")) for s in mine]
        axes[0].plot([i] * len(mae), mae, "o", color="C0")
        axes[0].bar(i, np.mean(mae), color="C0", alpha=0.3)
        for dx, share, marker, colour, text in (
                (-0.18, smooth, "o", "C1", "ridge: van crosses at the smoothed section"),
                (0.0, ascent, "s", "C2", "hill: carla_cola up by Route A"),
                (0.18, descent, "v", "C3", "hill: carla_cola down by Route B")):
            axes[1].plot(np.full(len(share), i + dx), share, marker, color=colour,
                         label=text if i == 0 else None)
    for ax in axes:
        ax.set_xticks(range(len(variants)), [tick_label(v) for v in variants], fontsize=8)
    axes[0].set_ylabel("MAE vs measured ground truth")
    axes[0].set_title("costmap error (mean over world × vehicle)")
    axes[1].set_ylabel("share of plans as claimed")
    axes[1].set_ylim(-0.05, 1.05)
    axes[1].set_title("Experiments 1–2 plans (each seed a marker)")
    axes[1].legend(loc="best", fontsize=7)
    fig.savefig(path, dpi=110)
    print(f"[map_inputs] wrote {path}")


def main() -> None:
    study = Study("map_inputs", __doc__, profile="demo", seeds=3, stores=True)
    parser = study.parser
    parser.add_argument("--variants", nargs="+", default=["rgbd", "geometry", "rgb", "shuffled"],
                        choices=list(VARIANTS))
    parser.add_argument("--out", type=Path, default=None,
                        help="where the variants' data and scores go (default: "
                             "<data>/studies/map_inputs)")
    parser.add_argument("--figure", type=Path, default=None, help="figure path (default: in --out)")
    parser.add_argument("--one", nargs=2, metavar=("VARIANT", "SEED"), help=argparse.SUPPRESS)
    args = study.parse()
    from dgt_lib.core import artifacts

    base = artifacts.data_root()
    out = (args.out or base / "studies" / "map_inputs").resolve()
    if args.one:
        result = score(args.one[0], args.profile, int(args.one[1]))
        write_scores(out / "scores" / f"{args.one[0]}_seed{args.one[1]}.json", result)
        return
    if args.stored:
        paths = [out / "scores" / f"{v}_seed{s}.json" for v in args.variants for s in study.seeds]
        scores = [json.loads(p.read_text()) for p in paths if p.exists()]
        if not scores:
            print(f"no stored scores under {out / 'scores'} for these seeds: run without "
                  "--stored first", file=sys.stderr)
            raise SystemExit(2)
    else:
        scores = [run_one(v, args.profile, s, base, out) for v in args.variants
                  for s in study.seeds]
    study.finish(tables(scores), seeds=sorted({s["seed"] for s in scores}),
                 variant=record_variant(scores))
    figure(scores, args.figure or out / "map_inputs.png")


if __name__ == "__main__":
    main()
