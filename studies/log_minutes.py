"""How many minutes of a new robot's driving does DGT-Map need?

A robot the kit never trained on (``examples/my_truck.toml``, a 4 t box truck) drives the
training world and leaves drive logs as a user's robot would (``dgt log record``: runs of
60 s with a stop after each, camera 10 Hz, odometry 50 Hz, command 20 Hz, jitter, dropped
frames, noisy odometry). Its drive is recorded as bag files, as a robot's recorder splits a
long drive: a first log of 30 runs, then logs of 10 more until the drive holds
:data:`MINUTES`' longest. A run ends early where the truck stalls for good, so a length is
counted in *labelled minutes* (the run's patches times ``collect.patch_interval_s``): the
logs of 1, 3, 10 and 30 minutes are the drive's first runs that hold that many. Each
length's logs are ingested as ``dgt log ingest`` does, and each head is scored on a held-out
log of three more runs, recorded with run seeds no training run has (the mean absolute
error of L̂ against the held-out labels):

- **prior**: the mean training label for every patch (what a head must beat);
- **zero-shot**: the vehicle-conditioned network answering for the truck's spec (no log);
- **few-shot**: a head on the multi-task network's frozen backbone fitted to the log
  (``dgt_lib.logs.heads.few_shot_head``);
- **scratch**: a network of the profile's recipe trained on the log alone.

The validation data (early stopping) is the last quarter of the log's runs, at least one
(for a log of one run: the last quarter of its patches). Per run seed S of the profile's
canonical run, the multi-task and the conditioned models of seed S are used; the training
runs have run seeds 100·S + 1, 2, … and the held-out runs 100·S + :data:`HELD_OUT_FIRST`, …

With ``--truth`` each head of the longest log (and the prior, a flat costmap) also maps the
hill and the ridge: its costmap is scored against the truck's measured ground truth there
(the ``ground_truth`` stage's drives, for the truck's spec) and plans Experiment 1's and
Experiment 2's queries (the profile's ``n_hill`` and ``n_ridge``; planned, not driven):
up by Route A and down by Route B on the hill, and which crossing of the ridge.
Scores per seed are stored under ``<data>/studies/log_minutes/`` (a rerun resumes)::

    DGT_DATA_DIR=/big/disk .venv/bin/python studies/log_minutes.py --profile demo --seeds 3 --truth
    … --seeds 3 --truth --stored --publish --figure docs/figures/log_minutes.png  # tables, record
"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from runner import Study, write_scores  # noqa: E402
from scarcity import interval  # noqa: E402

from dgt_lib.core import artifacts  # noqa: E402
from dgt_lib.core.config import Profile, get_profile  # noqa: E402
from dgt_lib.core.vehicle_file import load_vehicle  # noqa: E402
from dgt_lib.perception.dataset import SPLIT_NAMES, PatchDataset  # noqa: E402

ROBOT = Path(__file__).resolve().parents[1] / "examples" / "my_truck.toml"
MINUTES = (1.0, 3.0, 10.0, 30.0)
"""The logs' lengths [labelled minutes]."""
RUN_S = 60.0
FIRST_RUNS, MORE_RUNS, MAX_RUNS = 30, 10, 80
"""The drive's bag files: the first of 30 runs, then of 10 runs, at most 80 runs in all."""
HELD_OUT_RUNS, HELD_OUT_FIRST = 3, 90
"""The held-out log: 3 runs, run seeds 100·S + 90, 91, 92 (after every training run's)."""
VAL_SHARE = 0.25
"""The share of a log's runs (its last ones, at least one) that early stopping watches."""
HEADS = ("prior", "zero-shot", "few-shot", "scratch")
WORLDS = {"hill": "n_hill", "ridge": "n_ridge"}
"""The worlds mapped with ``--truth``, with the setting that counts their queries."""
TRAIN, VAL, TEST = (SPLIT_NAMES.index(s) for s in SPLIT_NAMES)


def _log(prof: Profile, name: str, seed: int, runs: int) -> PatchDataset:
    """A recorded and ingested log of ``runs`` drives of the robot on the training world
    (run seeds ``seed``, ``seed`` + 1, …)."""
    from dgt_lib.logs.ingest import ingest
    from dgt_lib.logs.record import record_log
    from dgt_lib.world.terrain import get_world

    robot = load_vehicle(ROBOT)
    cfg = replace(prof.collect, episode_duration_s=RUN_S)
    path = artifacts.data_root() / "studies" / "log_minutes" / "logs" / f"{name}.mcap"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        record_log(get_world("training", prof), robot, path, seed=seed, config=cfg, runs=runs)
    folder = Path(ingest(path, robot, cfg=cfg)["folder"])
    return PatchDataset.from_arrays(artifacts.load(folder / "dataset.npz"))


def run_minutes(log: PatchDataset, interval_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The log's runs in driving order and each run's labelled minutes."""
    runs, counts = np.unique(log.trajectory, return_counts=True)
    return runs, counts * interval_s / 60.0


def concatenate(parts: list[PatchDataset]) -> PatchDataset:
    """One drive of several logs: their runs in order, each with an id of its own."""
    arrays, offset = [], 0
    for part in parts:
        a = part.to_arrays()
        a["trajectory"] = a["trajectory"] - a["trajectory"].min() + offset
        offset = int(a["trajectory"].max()) + 1
        arrays.append(a)
    return PatchDataset.from_arrays({k: np.concatenate([a[k] for a in arrays])
                                     for k in arrays[0]})


def training_drive(prof: Profile, seed: int) -> PatchDataset:
    """The robot's drive for run seed ``seed``: bag files of :data:`FIRST_RUNS`, then
    :data:`MORE_RUNS` runs, until it holds ``max(MINUTES)`` labelled minutes."""
    parts, first = [], 1
    while not parts or run_minutes(concatenate(parts), prof.collect.patch_interval_s)[1].sum() \
            < max(MINUTES):
        runs = FIRST_RUNS if first == 1 else MORE_RUNS
        if first + runs - 1 > MAX_RUNS:
            raise SystemExit(f"{MAX_RUNS} runs hold fewer than {max(MINUTES):g} labelled "
                             "minutes: the robot stalls too often on the training world")
        name = f"{prof.name}_train{runs}_seed{seed}" + (f"_from{first}" if first > 1 else "")
        parts.append(_log(prof, name, 100 * seed + first, runs))
        first += runs
    return concatenate(parts)


def held_out_log(prof: Profile, seed: int) -> PatchDataset:
    """The held-out log of run seed ``seed`` (:data:`HELD_OUT_RUNS` runs)."""
    return _log(prof, f"{prof.name}_held_out{HELD_OUT_RUNS}_seed{seed}_from{HELD_OUT_FIRST}",
                100 * seed + HELD_OUT_FIRST, HELD_OUT_RUNS)


def first_runs(log: PatchDataset, minutes: float, interval_s: float) -> int:
    """How many of the log's first runs hold ``minutes`` labelled minutes."""
    held = np.cumsum(run_minutes(log, interval_s)[1])
    return int(np.searchsorted(held, minutes - 1e-9)) + 1


def study_data(log: PatchDataset, held_out: PatchDataset, n_runs: int) -> PatchDataset:
    """The first ``n_runs`` runs of ``log`` as training and validation (the last
    :data:`VAL_SHARE` of them, at least one; for one run its last quarter of patches) and
    ``held_out`` as the test split."""
    runs = np.unique(log.trajectory)[:n_runs]
    mine = log.subset(np.isin(log.trajectory, runs))
    split = np.full(len(mine), TRAIN, np.int8)
    if len(runs) > 1:
        n_val = max(1, round(VAL_SHARE * len(runs)))
        split[np.isin(mine.trajectory, runs[-n_val:])] = VAL
    else:
        split[int(0.75 * len(mine)):] = VAL
    test = held_out.to_arrays()
    arrays = {k: np.concatenate([v, test[k]])
              for k, v in replace(mine, split=split).to_arrays().items()}
    arrays["split"][len(mine):] = TEST
    arrays["trajectory"][len(mine):] += int(mine.trajectory.max()) + 1
    return PatchDataset.from_arrays(arrays)


def fitted_heads(prof: Profile, data: PatchDataset, seed: int) -> dict:
    """The few-shot head and the from-scratch network fitted to ``data``."""
    from dgt_lib.learning.run import train_model
    from dgt_lib.logs import heads
    from dgt_lib.stages.costmaps import load_model

    # the log's patches carry vehicle code 0: a one-head network of the recipe
    return {"few-shot": heads.few_shot_head(load_model(prof), data, ROBOT.stem),
            "scratch": train_model(data, prof.train, vehicles=("jeep",), seed=seed,
                                   progress=False).model}


def score_seed(prof: Profile, seed: int) -> dict:
    """Every head's held-out MAE for each log length (:data:`MINUTES`), with run seed
    ``seed``'s models."""
    from dgt_lib.logs import heads

    prof = replace(prof, seed=seed)
    log, held_out = training_drive(prof, seed), held_out_log(prof, seed)
    zero = heads.zero_shot_head(prof, load_vehicle(ROBOT))
    interval_s = prof.collect.patch_interval_s
    rows = []
    for minutes in MINUTES:
        n_runs = first_runs(log, minutes, interval_s)
        data = study_data(log, held_out, n_runs)
        errors = heads.compare_heads(data, {"zero-shot": zero}
                                     | fitted_heads(prof, data, seed))
        patches = int((data.split != TEST).sum())
        rows.append({"minutes": minutes, "runs": n_runs, "patches": patches,
                     "labelled_minutes": patches * interval_s / 60.0,
                     "held_out": errors["prior"]["n"],
                     "mae": {h: errors[h]["mae"] for h in HEADS}})
        print(f"seed {seed}, {minutes:g} min ({n_runs} runs, {patches} patches): " + ", ".join(
            f"{h} {rows[-1]['mae'][h]:.3f}" for h in HEADS), flush=True)
    return {"seed": seed, "rows": rows}


def truth_and_plans(prof: Profile, seed: int) -> dict:
    """The longest log's heads (and the prior, a flat costmap) on the hill and the ridge:
    each costmap against the truck's measured ground truth (MAE, over the measured samples
    on free cells) and the routes of its plans for the world's queries."""
    from dgt_lib.evaluation.queries import hill_queries, ridge_queries
    from dgt_lib.logs import heads
    from dgt_lib.stages.ground_truth import ensure_ground_truth
    from dgt_lib.world.terrain import get_world

    prof = replace(prof, seed=seed)
    robot = load_vehicle(ROBOT)
    log = training_drive(prof, seed)
    data = study_data(log, held_out_log(prof, seed),
                      first_runs(log, max(MINUTES), prof.collect.patch_interval_s))
    prior = float(data.labels[data.split == TRAIN].mean())
    models = {"zero-shot": heads.zero_shot_head(prof, robot)} | fitted_heads(prof, data, seed)
    draw = {"hill": hill_queries, "ridge": ridge_queries}
    out: dict = {"seed": seed, "prior_label": prior}
    for world_name, count in WORLDS.items():
        world = get_world(world_name, prof)
        truth = ensure_ground_truth(world_name, robot, prof)
        queries = draw[world_name](world, getattr(prof.experiments, count), prof.experiments,
                                   seed)
        costmaps = {}
        for name, model in models.items():
            maps, costmaps[name] = heads.world_maps(world, model, prof, progress=False)
        costmaps["prior"] = np.full_like(costmaps["zero-shot"], 1.0 - prior)
        for name in HEADS:
            out.setdefault(name, {})[world_name] = _score(costmaps[name], truth, maps, prof,
                                                          robot, queries, world)
        print(f"seed {seed}, {world_name}: " + "; ".join(
            f"{h} MAE {out[h][world_name]['mae']:.3f} {out[h][world_name]['routes']}"
            for h in HEADS), flush=True)
    return out


def _score(cost, truth, maps, prof, robot, queries, world) -> dict:
    """One costmap's accuracy against ``truth`` and its plans' routes, [[label, route]]."""
    from dgt_lib.evaluation.queries import classify_route
    from dgt_lib.navigation.planner import HybridAStar
    from dgt_lib.stages.ground_truth import score_costmap

    scores, _ = score_costmap(cost, truth, maps, prof)
    planner = HybridAStar.for_vehicle(cost, maps.occupancy, maps.grid, robot, prof.planner)
    routes = []
    for q in queries:
        plan = planner.plan(q.start, q.goal)
        routes.append([q.label, classify_route(world, plan.path) if plan.success else None])
    return {"mae": scores["mae"], "samples": scores["n"], "routes": routes}


PLAN_CLAIMS = (("hill", "ascent", "A"), ("hill", "descent", "B"), ("ridge", None, "smooth"))
"""The plans counted: ascents by Route A, descents by Route B, ridge crossings at the
smoothed section (the claims of Experiments 1 and 2 for the paper's vehicles)."""


def truth_tables(truths: list[dict]) -> dict[str, dict]:
    """Per head, the ground-truth MAE on each world (mean over the seeds, and per seed) and
    the plans of each :data:`PLAN_CLAIMS` kind, per seed."""
    from dgt_lib.records.study import table

    seeds = ", ".join(str(t["seed"]) for t in truths)
    mae_rows, plan_rows = [], []
    for name in HEADS:
        cells = []
        for world in WORLDS:
            values = [t[name][world]["mae"] for t in truths]
            cells.append(f"{np.mean(values):.3f} ({', '.join(f'{v:.3f}' for v in values)})")
        mae_rows.append([name, *cells])
        cells = []
        for world, label, route in PLAN_CLAIMS:
            counts = [(sum(r == route for lab, r in t[name][world]["routes"]
                           if label in (None, lab)),
                       sum(label in (None, lab) for lab, _ in t[name][world]["routes"]))
                      for t in truths]
            cells.append(", ".join(f"{k}/{n}" for k, n in counts))
        plan_rows.append([name, *cells])
    longest = f"{max(MINUTES):g}-minute"
    return {
        "truth": table(f"MAE of each head's costmap against the truck's measured ground truth "
                       f"({longest} log; mean over seeds {seeds}, then per seed)",
                       ["head", *(f"{w} MAE" for w in WORLDS)], mae_rows),
        "plans": table(f"Experiments 1 and 2 planned for the truck on each head's costmap "
                       f"({longest} log; per seed {seeds}; planned, not driven)",
                       ["head", "hill ascents by Route A", "hill descents by Route B",
                        "ridge crossings at the smoothed section"], plan_rows)}


def tables(scores: list[dict]) -> dict[str, dict]:
    """Held-out MAE per log length, mean ± 95 % t-interval over the seeds, and per seed."""
    from dgt_lib.records.study import table

    seeds = [s["seed"] for s in scores]
    mean_rows, seed_rows = [], []
    for i, minutes in enumerate(MINUTES):
        rows = [s["rows"][i] for s in scores]
        cells = [f"{minutes:g}", "{:.1f}".format(np.mean([r["runs"] for r in rows])),
                 "{:.0f}".format(np.mean([r["patches"] for r in rows]))]
        for h in HEADS:
            m, half = interval([r["mae"][h] for r in rows])
            cells.append(f"{m:.3f} ± {half:.3f}" if np.isfinite(half) else f"{m:.3f}")
        mean_rows.append(cells)
        for r, s in zip(rows, seeds, strict=True):
            best = min(HEADS, key=lambda h: r["mae"][h])
            seed_rows.append([f"{minutes:g}", str(s), str(r["runs"]),
                              *(f"{r['mae'][h]:.3f}" for h in HEADS), best])
    return {
        "minutes": table("Held-out MAE of L̂ for a robot never trained on, by the labelled "
                         "minutes of its drive log (mean ± 95 % t-interval over the seeds)",
                         ["labelled minutes", "runs", "patches", *HEADS], mean_rows),
        "per_seed": table("Held-out MAE per seed, and the closest head",
                          ["labelled minutes", "seed", "runs", *HEADS, "closest"], seed_rows)}


def figure(scores: list[dict], path: Path) -> None:
    """Held-out MAE against the log's labelled minutes, one line per head (means over the
    seeds; each seed's value as a dot)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 3.6), constrained_layout=True)
    for head, color, line in zip(HEADS, ("k", "C0", "C2", "C3"), (":", "-", "-", "--"),
                                 strict=True):
        per_seed = np.array([[r["mae"][head] for r in s["rows"]] for s in scores])
        ax.plot(MINUTES, per_seed.mean(axis=0), color=color, ls=line, marker="o", label=head)
        for values in per_seed:
            ax.plot(MINUTES, values, color=color, marker=".", ls="none", alpha=0.4)
    ax.set_xscale("log")
    ax.set_xticks(MINUTES, [f"{m:g}" for m in MINUTES])
    ax.set_xlabel("labelled minutes of the robot's drive log")
    ax.set_ylabel("held-out MAE of L̂")
    ax.set_ylim(bottom=0)
    ax.set_title(f"my_truck, never trained on ({len(scores)} seeds)", fontsize=10)
    ax.legend(fontsize=8)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"figure: {path}")


def stored(path: Path, make, rerun: bool) -> dict | None:
    """The scores at ``path``, made by ``make()`` and stored first unless ``rerun`` is off."""
    if not path.exists() and rerun:
        write_scores(path, make())
    return json.loads(path.read_text()) if path.exists() else None


def main() -> None:
    study = Study("log_minutes", __doc__, profile="demo", seeds=3, stores=True)
    study.parser.add_argument("--truth", action="store_true",
                              help="also score and plan the longest log's heads on the hill "
                                   "and the ridge against the truck's ground truth")
    study.parser.add_argument("--figure", type=Path, default=None,
                              help="figure path (default: in the scores' folder)")
    args = study.parse()
    prof = get_profile(args.profile)
    folder = artifacts.data_root() / "studies" / "log_minutes" / args.profile
    scores = [s for seed in study.seeds
              if (s := stored(folder / f"seed{seed}_minutes.json",
                              lambda seed=seed: score_seed(prof, seed), not args.stored))]
    if not scores:
        raise SystemExit(f"no stored scores in {folder}")
    truths = [t for seed in (study.seeds if args.truth else ())
              if (t := stored(folder / f"seed{seed}_truth.json",
                              lambda seed=seed: truth_and_plans(prof, seed), not args.stored))]
    figure(scores, args.figure or folder / "log_minutes.png")
    study.finish(tables(scores) | (truth_tables(truths) if truths else {}),
                 seeds=[s["seed"] for s in scores])


if __name__ == "__main__":
    main()
