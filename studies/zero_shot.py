"""A costmap for a vehicle that was never driven: each named vehicle left out of the
vehicle-conditioned network's training in turn, its costmap predicted from its spec alone
and scored against its measured ground truth, per run seed.

    .venv/bin/python studies/zero_shot.py --profile demo --seeds 3
    .venv/bin/python studies/zero_shot.py --profile demo --seeds 3 --stored --publish
    .venv/bin/python studies/zero_shot.py --profile demo --seeds 3 --generated 8
    .venv/bin/python studies/zero_shot.py --profile demo --seeds 3 --generated 8 --stored --publish

Per (seed, left-out vehicle) it builds through the cache (the profile's data directory,
``$DGT_DATA_DIR`` or ``data/``: the same collection, dataset, multi-task model and ground
truth as ``dgt reproduce``) the conditioned model trained without the vehicle, and scores
on every world whose experiments use the vehicle the maps of
:data:`zero_shot_scores.ZERO_SHOT_METHODS`: zero-shot, its own multi-task head, the
nearest seen vehicle's head (multi-task, and conditioned), Slope-Based from its climb; the
same predictors on the vehicle's test patches.
Where the vehicle is Experiment 1's (carla_cola, hill) or 2's (mercedes_van, ridge) every
map also plans the experiment's queries (the paper's 20 and 50; planned, not driven).
Each (seed, vehicle) is stored as ``<out>/scores/seed<S>_without_<vehicle>.json`` once
done, so an interrupted run resumes; then it prints the tables over seeds and draws
``<out>/zero_shot.png``. ``--stored``: tables and figure from the stored scores only.
``--generated N``: the conditioned networks also learn from N generated vehicles
(``conditioned.generated_vehicles``, docs/vehicles.md); scores and figure get ``_gen<N>``.

The tables (:func:`tables`): ``mae`` (MAE per world and left-out vehicle, each map),
``ratio`` (zero-shot ÷ own head per seed, its last row how many vehicles are within 25 %),
``patches`` (MAE on the vehicle's test patches) and ``plans`` (Experiments 1–2 planned on
each map); with ``--generated N`` (N > 0) also the list ``generated``, one line: how many
generated vehicles each left-out vehicle's network used. ``--publish`` writes them to
``docs/runs/studies/zero_shot[-<variant>]_<profile>_<processor>_<date>.json``: the variant
is ``gen<N>`` with generated vehicles, joined by ``without-<vehicles>`` (the left-out
vehicles scored, ``-``-joined) when not all four are, so a partial run never overwrites the
full record (``zero_shot-gen8-without-carla_cola_…``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from planned import CLAIMS, claim_share
from runner import Study
from zero_shot_scores import ZERO_SHOT_METHODS

from dgt_lib.core.config import VEHICLES
from dgt_lib.records.study import table


def suffix(generated: int) -> str:
    """``_gen<N>`` for the runs with N generated training vehicles, else nothing."""
    return f"_gen{generated}" if generated else ""


def score_path(out: Path, seed: int, vehicle: str, generated: int = 0) -> Path:
    return out / "scores" / f"seed{seed}_without_{vehicle}{suffix(generated)}.json"


def run_one(profile: str, seed: int, vehicle: str, out: Path, generated: int = 0) -> dict:
    """The stored scores of (seed, left-out vehicle), computed (through the cache) if missing."""
    path = score_path(out, seed, vehicle, generated)
    if path.exists():
        return json.loads(path.read_text())
    from zero_shot_scores import zero_shot_scores

    from dgt_lib.core.config import get_profile

    print(f"[zero_shot] seed {seed}, {vehicle} left out, {generated} generated vehicles",
          flush=True)
    prof = get_profile(profile).with_(seed=seed)
    if generated:
        prof = prof.with_overrides({"conditioned.generated_vehicles": generated})
    result = {"profile": profile, **zero_shot_scores(vehicle, prof)}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=1))
    return result


def generated_line(scores: list[dict]) -> str:
    """How many generated vehicles the conditioned networks learned from, and per left-out
    vehicle how many of them its zero-shot network used (near copies skipped)."""
    n = sorted({s.get("generated", 0) for s in scores})
    used = {v: sorted({s.get("generated_used", 0) for s in scores if s["vehicle"] == v})
            for v in VEHICLES if any(s["vehicle"] == v for s in scores)}
    return (f"Generated training vehicles: {', '.join(map(str, n))} (used by the network "
            "without each vehicle, over seeds: "
            + "; ".join(f"{v} {', '.join(map(str, u))}" for v, u in used.items()) + ")")


def mae_table(scores: list[dict]) -> dict:
    """MAE per (world, left-out vehicle) and method, mean ± std over seeds."""
    seeds = sorted({s["seed"] for s in scores})
    rows = []
    for vehicle in VEHICLES:
        mine = [s for s in scores if s["vehicle"] == vehicle]
        if not mine:
            continue
        nearest = ", ".join(sorted({s["nearest"] for s in mine}))
        for world in dict.fromkeys(r["world"] for r in mine[0]["rows"]):
            cells = []
            for m in ZERO_SHOT_METHODS:
                x = [r["mae"] for s in mine for r in s["rows"]
                     if (r["world"], r["method"]) == (world, m)]
                cells.append(f"{np.mean(x):.3f} ± {np.std(x):.3f}")
            rows.append([world, f"{vehicle} (nearest: {nearest})",
                         ", ".join(str(s["seed"]) for s in mine), *cells])
    return table(f"MAE against the measured ground truth (mean ± std over seeds {seeds}; "
                 "the vehicle never driven by the zero-shot network)",
                 ["world", "vehicle", "seeds", *ZERO_SHOT_METHODS], rows)


WITHIN = 1.25
"""The aim for a zero-shot map: MAE at most 25 % above the own head's (ratio ≤ 1.25)."""


def ratio_table(scores: list[dict]) -> dict:
    """Zero-shot MAE ÷ own-head MAE per (world, vehicle) and seed, and in a last row per seed
    how many vehicles are within :data:`WITHIN` on every world they are scored on."""
    seeds = sorted({s["seed"] for s in scores})
    pct = f"{100 * (WITHIN - 1):.0f} %"
    rows = []
    within = {k: [] for k in seeds}
    for vehicle in VEHICLES:
        mine = {s["seed"]: s for s in scores if s["vehicle"] == vehicle}
        if not mine:
            continue
        ratios = {k: {r["world"]: r["mae"] for r in s["rows"] if r["method"] == "zero-shot"}
                  for k, s in mine.items()}
        for k, s in mine.items():
            own = {r["world"]: r["mae"] for r in s["rows"] if r["method"] == "own head"}
            ratios[k] = {w: z / own[w] for w, z in ratios[k].items()}
            within[k].append(all(x <= WITHIN for x in ratios[k].values()))
        for world in dict.fromkeys(w for k in ratios for w in ratios[k]):
            rows.append([world, vehicle, *(f"{ratios[k][world]:.2f}" if k in ratios else "–"
                                           for k in seeds)])
    rows.append([f"**vehicles within {pct}**", "",
                 *(f"{sum(within[k])} of {len(within[k])}" for k in seeds)])
    return table(f"Zero-shot MAE ÷ own head's MAE (≤ {WITHIN}: within {pct}), per seed",
                 ["world", "vehicle", *(f"seed {k}" for k in seeds)], rows)


def patch_table(scores: list[dict]) -> dict:
    """MAE on each left-out vehicle's test patches, mean ± std over seeds."""
    rows = []
    for vehicle in VEHICLES:
        mine = [s for s in scores if s["vehicle"] == vehicle and "patches" in s]
        if mine:
            cells = [f"{np.mean([s['patches'][m]['mae'] for s in mine]):.3f} ± "
                     f"{np.std([s['patches'][m]['mae'] for s in mine]):.3f}"
                     for m in ZERO_SHOT_METHODS]
            n = ", ".join(str(s["patches"]["zero-shot"]["n"]) for s in mine)
            rows.append([vehicle, n, *cells])
    return table("MAE on the vehicle's test patches against their labels L (mean ± std over "
                 "seeds)", ["vehicle", "patches", *ZERO_SHOT_METHODS], rows)


def plan_table(scores: list[dict]) -> dict:
    """The plan claims per map, one count per seed."""
    rows = []
    for m in ZERO_SHOT_METHODS:
        cols = []
        for exp, label, route in CLAIMS:
            mine = sorted((s for s in scores if exp in s["plans"]), key=lambda s: s["seed"])
            cols.append(", ".join("{}/{}".format(*claim_share(s["plans"][exp][m], label, route))
                                  for s in mine) or "–")
        rows.append([m, *cols])
    return table("Plans of Experiments 1–2 on each map (planned, not driven; one count per "
                 "seed)", ["map", "hill ascents by Route A", "hill descents by Route B",
                           "ridge crossings at the smoothed section"], rows)


def tables(scores: list[dict]) -> dict[str, dict]:
    """The study's tables (:func:`~dgt_lib.records.study.table`): ``mae``, ``ratio``,
    ``patches`` and ``plans``."""
    return {"mae": mae_table(scores), "ratio": ratio_table(scores),
            "patches": patch_table(scores), "plans": plan_table(scores)}


def record_variant(scores: list[dict], generated: int) -> str:
    """The record's variant: ``gen<N>`` with N generated vehicles, and ``without-<v>-…``
    (the left-out vehicles scored, in :data:`VEHICLES` order) unless all four are."""
    scored = [v for v in VEHICLES if any(s["vehicle"] == v for s in scores)]
    parts = [f"gen{generated}"] if generated else []
    if len(scored) < len(VEHICLES):
        parts.append("without-" + "-".join(scored))
    return "-".join(parts)


def figure(scores: list[dict], path: Path) -> None:
    """MAE per left-out vehicle and world, one group per (world, vehicle), a bar per map
    (mean over seeds) with each seed a dot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pairs = list(dict.fromkeys((r["world"], r["vehicle"]) for s in scores for r in s["rows"]))
    fig, ax = plt.subplots(figsize=(2.2 * len(pairs) + 2, 3.8), constrained_layout=True)
    width = 0.8 / len(ZERO_SHOT_METHODS)
    for j, m in enumerate(ZERO_SHOT_METHODS):
        for i, pair in enumerate(pairs):
            x = [r["mae"] for s in scores for r in s["rows"]
                 if (r["world"], r["vehicle"], r["method"]) == (*pair, m)]
            pos = i - 0.4 + (j + 0.5) * width
            ax.bar(pos, np.mean(x), width, color=f"C{j}", alpha=0.5,
                   label=m if i == 0 else None)
            ax.plot([pos] * len(x), x, "o", color=f"C{j}", ms=3)
    ax.set_xticks(range(len(pairs)), [f"{v}\non {w}" for w, v in pairs], fontsize=8)
    ax.set_ylabel("MAE vs measured ground truth")
    ax.set_title("A vehicle never driven: zero-shot costmap against the alternatives")
    ax.legend(fontsize=7, loc="best")
    fig.savefig(path, dpi=110)
    print(f"[zero_shot] wrote {path}")


def main() -> None:
    study = Study("zero_shot", __doc__, profile="demo", seeds=3, stores=True)
    parser = study.parser
    parser.add_argument("--vehicles", nargs="+", default=list(VEHICLES), choices=VEHICLES,
                        help="the vehicles to leave out, each in turn (default: all four)")
    parser.add_argument("--out", type=Path, default=None,
                        help="where the scores and figure go (default: <data>/studies/zero_shot)")
    parser.add_argument("--figure", type=Path, default=None, help="figure path (default: in --out)")
    parser.add_argument("--generated", type=int, default=0, metavar="N",
                        help="generated training vehicles for the conditioned networks "
                             "(conditioned.generated_vehicles; default 0: the named only)")
    args = study.parse()
    from dgt_lib.core import artifacts

    out = (args.out or artifacts.data_root() / "studies" / "zero_shot").resolve()
    if args.stored:
        paths = [score_path(out, s, v, args.generated) for s in study.seeds
                 for v in args.vehicles]
        scores = [json.loads(p.read_text()) for p in paths if p.exists()]
        if not scores:
            raise SystemExit(f"no stored scores under {out / 'scores'}")
    else:
        scores = [run_one(args.profile, s, v, out, args.generated) for s in study.seeds
                  for v in args.vehicles]
    study.finish(tables(scores),
                 lists={"generated": [generated_line(scores)]} if args.generated else None,
                 seeds=sorted({s["seed"] for s in scores}),
                 variant=record_variant(scores, args.generated))
    figure(scores, args.figure or out / f"zero_shot{suffix(args.generated)}.png")


if __name__ == "__main__":
    main()
