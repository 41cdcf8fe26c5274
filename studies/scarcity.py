"""When does multi-task learning help? The paper's Claim 4 ("especially in cases where
vehicle-specific data is limited") measured: for the vw_van and for carla_cola in turn, only a
fraction f of that vehicle's training runs is kept (whole runs; every other vehicle keeps all
its data), the multi-task model and that vehicle's single-task model are trained with the
profile's recipe, and both are scored against the measured ground truth.

    .venv/bin/python studies/scarcity.py --profile demo --seeds 3
    .venv/bin/python studies/scarcity.py --profile demo --seeds 3 --closed-loop
    .venv/bin/python studies/scarcity.py --profile demo --seeds 3 --stored --publish

Per (vehicle, f, run seed) the pair of models is trained in its own data directory
``<out>/<vehicle>_f<f>/`` (f = 1 is the profile's own run, ``$DGT_DATA_DIR`` or ``data/``),
linked to the run's episodes, BEV maps, dataset and ground truth, so only the models and
their costmaps are built; everything is cached and resumable like the pipeline's stages
(``train.scarce_vehicle`` / ``train.scarce_fraction``, :mod:`dgt_lib.learning.scarcity`).
The scores go to ``<out>/scores/<vehicle>_f<f>_seed<S>.json``: the vehicle's training runs
and patches kept, MAE, Spearman ρ and directional contrast of each costmap on the vehicle's
ground-truth world, the paired test between them and the test-split MSE of each head.

``--closed-loop``: at the fraction where the two costmaps differ most (mean MAE difference
over the seeds, f < 1), the vehicle's closed-loop experiment runs in every seed — the vw_van's
is Experiment 3 (same query rule, Binary as the floor), carla_cola's Experiment 1 (the hill).
Then the tables over seeds and ``<out>/scarcity.png``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
from runner import Study, link, stored_or_run, write_scores

from dgt_lib.records.study import table

STUDIED = ("vw_van", "carla_cola")
FRACTIONS = (1.0, 0.3, 0.1, 0.03)
CLOSED_LOOP = {"vw_van": "experiment3", "carla_cola": "experiment1"}
"""Each studied vehicle's closed-loop experiment."""
SHARED = ("episodes", "bev", "occupancy", "dataset.npz", "dataset.npz.meta.json")
"""What a thinned run shares with the profile's own run (per seed)."""


def variant(vehicle: str, fraction: float) -> str:
    """A variant's name: ``vw_van_f0.1``."""
    return f"{vehicle}_f{fraction:g}"


def settings(vehicle: str, fraction: float) -> dict[str, object]:
    """The ``--set`` settings of a variant (none at f = 1: the profile's own run)."""
    if fraction == 1.0:
        return {}
    return {"train.scarce_vehicle": vehicle, "train.scarce_fraction": fraction}


def prepare(vehicle: str, fraction: float, profile: str, seed: int, base: Path,
            out: Path) -> Path:
    """The variant's data directory, linked to the profile's own run."""
    if fraction == 1.0:
        return base
    root = out / variant(vehicle, fraction)
    link(base / profile / "ground_truth", root / profile / "ground_truth")
    for name in SHARED:
        link(base / profile / f"seed-{seed}" / name, root / profile / f"seed-{seed}" / name)
    return root


def score(vehicle: str, fraction: float, profile: str, seed: int) -> dict:
    """Train (through the cache) and score one variant in one seed; runs in the variant's
    own process (its ``DGT_DATA_DIR``)."""
    from dgt_lib.core.config import VEHICLES, get_profile
    from dgt_lib.evaluation.accuracy import paired_comparison
    from dgt_lib.learning.scarcity import keep_runs
    from dgt_lib.perception.dataset import TRAIN
    from dgt_lib.stages.costmaps import EXPERIMENT_VEHICLES
    from dgt_lib.stages.dataset import ensure_dataset
    from dgt_lib.stages.ground_truth import GROUND_TRUTH_WORLDS, ensure_ground_truths, score_world
    from dgt_lib.stages.train import ensure_model

    prof = get_profile(profile).with_(seed=seed).with_overrides(settings(vehicle, fraction))
    dataset = ensure_dataset(prof)
    heads = {"dgt": ensure_model(prof, dataset, "multitask"),
             "single-task": ensure_model(prof, dataset, f"single:{vehicle}")}
    thinned = keep_runs(dataset, vehicle, fraction, seed)
    mine = (thinned.vehicle == VEHICLES.index(vehicle)) & (thinned.split == TRAIN)
    worlds = [w for w in GROUND_TRUTH_WORLDS if vehicle in EXPERIMENT_VEHICLES[w]]
    truths = ensure_ground_truths([(w, vehicle) for w in worlds], prof)
    accuracy, paired = [], []
    for w in worlds:
        rows, samples = score_world(w, truths, prof, methods=tuple(heads))
        accuracy += [{k: r[k] for k in ("world", "method", "n", "mae", "spearman", "contrast",
                                        "contrast_true", "sign_agreement")} for r in rows]
        (mt, truth), (st, _) = samples[(w, vehicle, "dgt")], samples[(w, vehicle, "single-task")]
        paired.append({"world": w, **paired_comparison(mt, st, truth),
                       "mae_difference_ci": mae_difference_ci(mt, st, truth, seed)})
    return {"vehicle": vehicle, "fraction": fraction, "seed": seed,
            "runs": int(len(np.unique(thinned.trajectory[mine]))), "patches": int(mine.sum()),
            "accuracy": accuracy, "paired": paired,
            "test_mse": {m: r.metrics[vehicle]["mse"] for m, r in heads.items()}}


def mae_difference_ci(multi: np.ndarray, single: np.ndarray, truth: np.ndarray, seed: int,
                      n_boot: int = 2000) -> list[float]:
    """95 % bootstrap interval of MAE(multi-task) − MAE(single-task) over the scored samples
    (paired: each resample draws the same samples for both maps)."""
    d = np.abs(multi - truth) - np.abs(single - truth)
    if len(d) == 0:
        return [math.nan, math.nan]
    rng = np.random.default_rng(seed)
    means = d[rng.integers(0, len(d), size=(n_boot, len(d)))].mean(axis=1)
    return [float(x) for x in np.percentile(means, [2.5, 97.5])]


def run_one(vehicle: str, fraction: float, profile: str, seed: int, base: Path,
            out: Path) -> dict:
    """The stored scores of (vehicle, fraction, seed), computed in a subprocess if missing."""
    path = out / "scores" / f"{variant(vehicle, fraction)}_seed{seed}.json"
    if path.exists():
        return json.loads(path.read_text())
    root = prepare(vehicle, fraction, profile, seed, base, out)
    return stored_or_run(path, root, [__file__, "--one", vehicle, str(fraction), str(seed),
                                      "--profile", profile, "--out", str(out)],
                         f"{variant(vehicle, fraction)} seed {seed}")


def thinned_scores(runs: list[tuple[str, float, int]], profile: str, base: Path,
                   out: Path) -> list[dict]:
    """The scores of every (vehicle, fraction, seed) of ``runs``; a fraction that keeps as
    many runs as a larger one (the same runs: the draw is nested) is skipped and said so."""
    from dgt_lib.learning.scarcity import runs_kept

    scores: list[dict] = []
    for v, f, seed in sorted(runs, key=lambda r: (r[0], r[2], -r[1])):
        larger = [s for s in scores if (s["vehicle"], s["seed"]) == (v, seed)]
        if f < 1 and larger:
            every = next((s["runs"] for s in larger if s["fraction"] == 1.0), None)
            if every is not None and runs_kept(every, f) == larger[-1]["runs"]:
                print(f"[scarcity] {variant(v, f)} seed {seed}: keeps the same "
                      f"{larger[-1]['runs']} run(s) as f = {larger[-1]['fraction']:g}; skipped")
                continue
        scores.append(run_one(v, f, profile, seed, base, out))
    return scores


def mae(s: dict, method: str) -> float:
    """A score's MAE of ``method`` over the vehicle's ground-truth worlds (sample-weighted)."""
    rows = [r for r in s["accuracy"] if r["method"] == method]
    return float(sum(r["mae"] * r["n"] for r in rows) / sum(r["n"] for r in rows))


def interval(values: list[float]) -> tuple[float, float]:
    """Mean and the half-width of its 95 % t-interval over seeds (NaN for one seed: no
    interval)."""
    from scipy import stats

    x = np.asarray(values, float)
    if len(x) < 2:
        return float(x.mean()), float("nan")
    return float(x.mean()), float(stats.t.ppf(0.975, len(x) - 1) * x.std(ddof=1)
                                  / math.sqrt(len(x)))


def most_different(scores: list[dict], vehicle: str) -> float:
    """The fraction f < 1 where the two costmaps' MAEs differ most (mean over seeds)."""
    gaps = {}
    for f in FRACTIONS[1:]:
        mine = [s for s in scores if s["vehicle"] == vehicle and s["fraction"] == f]
        if mine:
            gaps[f] = abs(np.mean([mae(s, "dgt") - mae(s, "single-task") for s in mine]))
    return max(gaps, key=gaps.get)


def closed_loop(vehicle: str, fraction: float, profile: str, seed: int, base: Path,
                out: Path) -> dict:
    """The vehicle's closed-loop experiment with the thinned models (cached, resumable):
    {method: [arrived, trials]} for that vehicle."""
    path = out / "scores" / f"{variant(vehicle, fraction)}_seed{seed}_closed_loop.json"
    root = prepare(vehicle, fraction, profile, seed, base, out)
    return stored_or_run(path, root, [__file__, "--loop", vehicle, str(fraction), str(seed),
                                      "--profile", profile, "--out", str(out)],
                         f"{CLOSED_LOOP[vehicle]} at {variant(vehicle, fraction)} seed {seed}")


def run_closed_loop(vehicle: str, fraction: float, profile: str, seed: int) -> dict:
    """In the variant's own process: its closed-loop experiment, counted for ``vehicle``."""
    from dgt_lib.core.config import get_profile
    from dgt_lib.stages.experiments import ensure_experiment

    prof = get_profile(profile).with_(seed=seed).with_overrides(settings(vehicle, fraction))
    result = ensure_experiment(CLOSED_LOOP[vehicle], prof)
    return {"vehicle": vehicle, "fraction": fraction, "seed": seed,
            "experiment": CLOSED_LOOP[vehicle],
            "arrived": {m: list(kn) for m, kn in result.counts(vehicle).items()}}


def _f(x: float, d: int = 3) -> str:
    return "—" if not math.isfinite(x) else f"{x:.{d}f}"


def tables(scores: list[dict], loops: list[dict]) -> dict[str, dict]:
    """The study's tables (:func:`~dgt_lib.records.study.table`): per vehicle and fraction
    the data kept and both maps' accuracy over seeds (``accuracy``), per seed the paired MAE
    difference (``paired``) and, when driven, the closed loop (``closed_loop``)."""
    seeds = sorted({s["seed"] for s in scores})
    accuracy, paired = [], []
    for v in STUDIED:
        for f in FRACTIONS:
            mine = [s for s in scores if s["vehicle"] == v and s["fraction"] == f]
            if not mine:
                continue
            cells = [v, f"{f:g}", "{:.0f}".format(np.mean([s["runs"] for s in mine])),
                     "{:.0f}".format(np.mean([s["patches"] for s in mine]))]
            for key in ("mae", "spearman"):
                for m in ("dgt", "single-task"):
                    vals = [mae(s, m) if key == "mae" else
                            np.mean([r[key] for r in s["accuracy"] if r["method"] == m])
                            for s in mine]
                    mean, half = interval(vals)
                    cells.append(f"{_f(mean)} ± {_f(half)}")
            con = [np.mean([[r["contrast"] for r in s["accuracy"] if r["method"] == m]
                            for s in mine]) for m in ("dgt", "single-task")]
            true = np.mean([r["contrast_true"] for s in mine for r in s["accuracy"]])
            accuracy.append([*cells, f"{con[0]:.2f} / {con[1]:.2f} / {true:.2f}"])
            paired.append([v, f"{f:g}", *(_difference(next(
                (s for s in mine if s["seed"] == seed), None)) for seed in seeds)])
    out = {"accuracy": table(
        "Accuracy against the measured ground truth, mean ± 95 % t-interval over the seeds "
        "(contrast: mean |C(θ) − C(θ+π)| over the directional pairs)",
        ["vehicle", "f", "runs kept", "patches", "MAE multi-task", "MAE single-task",
         "ρ multi-task", "ρ single-task", "contrast multi / single / true"], accuracy),
        "paired": table(
        "MAE multi-task − single-task per seed (95 % paired bootstrap interval; negative: "
        "multi-task closer)", ["vehicle", "f", *(f"seed {s}" for s in seeds)], paired)}
    if loops:
        out["closed_loop"] = table(
            "Closed loop at the fraction where the maps differ most (arrived / trials per "
            "seed; pooled, with its Wilson 95 % interval)",
            ["vehicle", "experiment", "f", "method", "per seed", "pooled"], _loop_rows(loops))
    return out


def _loop_rows(loops: list[dict]) -> list[list[str]]:
    """The closed loop's rows: per vehicle and method, arrivals per seed and pooled."""
    from dgt_lib.evaluation.statistics import wilson_interval
    from dgt_lib.mapping.methods import METHOD_LABELS

    rows = []
    for v in STUDIED:
        mine = sorted((x for x in loops if x["vehicle"] == v), key=lambda x: x["seed"])
        for m in mine[0]["arrived"] if mine else {}:
            k, n = (sum(x["arrived"][m][i] for x in mine) for i in (0, 1))
            lo, hi = wilson_interval(k, n)
            rows.append([v, mine[0]["experiment"], f"{mine[0]['fraction']:g}",
                         METHOD_LABELS.get(m, m),
                         ", ".join("{}/{}".format(*x["arrived"][m]) for x in mine),
                         f"{k}/{n} ({100 * lo:.0f}–{100 * hi:.0f} %)"])
    return rows


def _difference(s: dict | None) -> str:
    """One seed's MAE multi-task − single-task and its paired bootstrap interval."""
    if s is None:
        return "—"
    lo = min(p["mae_difference_ci"][0] for p in s["paired"])
    hi = max(p["mae_difference_ci"][1] for p in s["paired"])
    return f"{mae(s, 'dgt') - mae(s, 'single-task'):+.3f} [{lo:+.3f}, {hi:+.3f}]"


def figure(scores: list[dict], path: Path) -> None:
    """MAE against the vehicle's training patches, multi-task vs single-task, each seed a dot
    and the mean ± 95 % t-interval a line, one panel per vehicle scored."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    vehicles = [v for v in STUDIED if any(s["vehicle"] == v for s in scores)]
    fig, axes = plt.subplots(1, len(vehicles), figsize=(5 * len(vehicles), 3.8),
                             constrained_layout=True, squeeze=False)
    for ax, v in zip(axes[0], vehicles, strict=True):
        ax.set_title(v)
        for m, colour, label in (("dgt", "C0", "multi-task"), ("single-task", "C3",
                                                                "single-task")):
            xs, means, halves = [], [], []
            for f in FRACTIONS:
                mine = [s for s in scores if s["vehicle"] == v and s["fraction"] == f]
                if not mine:
                    continue
                vals = [mae(s, m) for s in mine]
                ax.plot([s["patches"] for s in mine], vals, ".", color=colour, alpha=0.5)
                xs.append(np.mean([s["patches"] for s in mine]))
                mean, half = interval(vals)
                means.append(mean)
                halves.append(half)
            ax.errorbar(xs, means, yerr=halves, color=colour, marker="o", capsize=3,
                        label=label)
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())  # decades only: no crowded labels
        ax.set_xlabel(f"{v} training patches (kept runs' patches)")
        ax.set_ylabel("MAE vs measured ground truth")
        ax.legend(fontsize=8)
    n_seeds = len({s["seed"] for s in scores})
    spread = (f"mean ± 95 % interval over {n_seeds} seeds" if n_seeds > 1 else
              "one seed: no interval over seeds")
    fig.suptitle(f"When does multi-task help?\nError against vehicle data ({spread})",
                 fontsize=10)
    fig.savefig(path, dpi=110)
    print(f"[scarcity] wrote {path}")


def main() -> None:
    study = Study("scarcity", __doc__, profile="demo", seeds=3, stores=True)
    parser = study.parser
    parser.add_argument("--vehicles", nargs="+", default=list(STUDIED), choices=STUDIED)
    parser.add_argument("--fractions", type=float, nargs="+", default=list(FRACTIONS))
    parser.add_argument("--closed-loop", action="store_true",
                        help="also each vehicle's closed-loop experiment at the fraction where "
                             "the two maps differ most")
    parser.add_argument("--out", type=Path, default=None,
                        help="where the variants' data and scores go (default: "
                             "<data>/studies/scarcity)")
    parser.add_argument("--figure", type=Path, default=None, help="figure path (default: in --out)")
    parser.add_argument("--one", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("--loop", nargs=3, help=argparse.SUPPRESS)
    args = study.parse()
    from dgt_lib.core import artifacts

    base = artifacts.data_root()
    out = (args.out or base / "studies" / "scarcity").resolve()
    for flag, work, suffix in ((args.one, score, ""), (args.loop, run_closed_loop,
                                                        "_closed_loop")):
        if flag:
            v, f, seed = flag[0], float(flag[1]), int(flag[2])
            write_scores(out / "scores" / f"{variant(v, f)}_seed{seed}{suffix}.json",
                         work(v, f, args.profile, seed))
            return
    runs = [(v, f, s) for v in args.vehicles for f in args.fractions for s in study.seeds]
    if args.stored:
        paths = [out / "scores" / f"{variant(v, f)}_seed{s}.json" for v, f, s in runs]
        scores = [json.loads(p.read_text()) for p in paths if p.exists()]
        loops = [x for x in (json.loads(p.read_text())
                             for p in sorted(out.glob("scores/*_closed_loop.json")))
                 if x["vehicle"] in args.vehicles and x["seed"] in study.seeds]
        if not scores:
            print(f"no stored scores under {out / 'scores'} for these seeds: run without "
                  "--stored first", file=sys.stderr)
            raise SystemExit(2)
    else:
        scores = thinned_scores(runs, args.profile, base, out)
        loops = []
        if args.closed_loop:
            for v in args.vehicles:
                f = most_different(scores, v)
                loops += [closed_loop(v, f, args.profile, s, base, out)
                          for s in study.seeds]
    study.finish(tables(scores, loops), seeds=sorted({s["seed"] for s in scores}),
                 variant="" if set(args.vehicles) == set(STUDIED) else "-".join(args.vehicles))
    figure(scores, args.figure or out / "scarcity.png")


if __name__ == "__main__":
    main()
