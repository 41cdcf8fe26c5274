"""How many minutes of a new robot's driving does DGT-Map need?

A robot the kit never trained on (``examples/my_truck.toml``, a 4 t box truck) drives the
training world and leaves drive logs as a user's robot would (``dgt log record``: runs of
60 s with a stop after each, camera 10 Hz, odometry 50 Hz, command 20 Hz, jitter, dropped
frames, noisy odometry). Logs of 1, 3, 10 and 30 runs (the first runs of one 30-run log) are
ingested as ``dgt log ingest`` does, and each head is scored on a held-out log of three more
runs, recorded with another seed (the mean absolute error of L̂ against the held-out
labels). A run ends early where the truck stalls for good, so a log's length is given as
its *labelled minutes*: its patches times ``collect.patch_interval_s``.

- **prior**: the mean training label for every patch (what a head must beat);
- **zero-shot**: the vehicle-conditioned network answering for the truck's spec (no log);
- **few-shot**: a head on the multi-task network's frozen backbone fitted to the log
  (``dgt_lib.logs.heads.few_shot_head``);
- **scratch**: a network of the profile's recipe trained on the log alone.

The validation data (early stopping) is the log's last run (for one run: the last quarter
of its patches). Per run seed S of the profile's canonical run, the multi-task and the
conditioned models of seed S are used and the logs are recorded with seeds 100·S + 1
(training) and 100·S + 2 (held out). With ``--hill`` the longest log's few-shot head and the
zero-shot head also plan Experiment 1's queries on the hill: up by Route A, down by B?
Scores per seed are stored under ``<data>/studies/log_minutes/`` (a rerun resumes)::

    DGT_DATA_DIR=/big/disk .venv/bin/python studies/log_minutes.py --profile demo --seeds 3 --hill
    … --seeds 3 --stored --publish --figure docs/figures/log_minutes.png  # tables, record
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
RUNS = (1, 3, 10, 30)
RUN_S = 60.0
HELD_OUT_RUNS = 3
HEADS = ("prior", "zero-shot", "few-shot", "scratch")
TRAIN, VAL, TEST = (SPLIT_NAMES.index(s) for s in SPLIT_NAMES)


def _log(prof: Profile, name: str, seed: int, runs: int) -> PatchDataset:
    """A recorded and ingested log of ``runs`` drives of the robot on the training world."""
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


def study_data(log: PatchDataset, held_out: PatchDataset, n_runs: int) -> PatchDataset:
    """The first ``n_runs`` runs of ``log`` as training and validation (the last run, or
    for one run its last quarter of patches) and ``held_out`` as the test split."""
    runs = np.unique(log.trajectory)[:n_runs]
    mine = log.subset(np.isin(log.trajectory, runs))
    split = np.full(len(mine), TRAIN, np.int8)
    if len(runs) > 1:
        split[mine.trajectory == runs[-1]] = VAL
    else:
        split[int(0.75 * len(mine)):] = VAL
    test = held_out.to_arrays()
    arrays = {k: np.concatenate([v, test[k]])
              for k, v in replace(mine, split=split).to_arrays().items()}
    arrays["split"][len(mine):] = TEST
    arrays["trajectory"][len(mine):] += int(mine.trajectory.max()) + 1
    return PatchDataset.from_arrays(arrays)


def score_seed(prof: Profile, seed: int) -> dict:
    """Every head's held-out MAE for each log length (:data:`RUNS`), with run seed
    ``seed``'s models."""
    from dgt_lib.learning.run import train_model
    from dgt_lib.logs import heads
    from dgt_lib.stages.costmaps import load_model

    prof = replace(prof, seed=seed)
    log = _log(prof, f"{prof.name}_train{max(RUNS)}_seed{seed}", 100 * seed + 1, max(RUNS))
    held_out = _log(prof, f"{prof.name}_held_out_seed{seed}", 100 * seed + 2, HELD_OUT_RUNS)
    robot = load_vehicle(ROBOT)
    backbone = load_model(prof)
    zero = heads.zero_shot_head(prof, robot)
    rows = []
    for n_runs in RUNS:
        data = study_data(log, held_out, n_runs)
        few = heads.few_shot_head(backbone, data, robot.name)
        # the log's patches carry vehicle code 0: a one-head network of the recipe
        scratch = train_model(data, prof.train, vehicles=("jeep",), seed=seed,
                              progress=False).model
        errors = heads.compare_heads(data, {"zero-shot": zero, "few-shot": few,
                                            "scratch": scratch})
        patches = int((data.split != TEST).sum())
        rows.append({"runs": n_runs, "patches": patches,
                     "minutes": patches * prof.collect.patch_interval_s / 60.0,
                     "held_out": errors["prior"]["n"],
                     "mae": {h: errors[h]["mae"] for h in HEADS}})
        print(f"seed {seed}, {n_runs} runs ({patches} patches): " + ", ".join(
            f"{h} {rows[-1]['mae'][h]:.3f}" for h in HEADS), flush=True)
    return {"seed": seed, "rows": rows}


def hill_routes(prof: Profile, seed: int) -> dict:
    """Experiment 1's queries (the profile's ``n_hill``, alternating up and down) planned for
    the truck on the hill with the few-shot head of the longest log and the zero-shot head:
    how many ascents take Route A and how many descents Route B (planned, not driven)."""
    from dgt_lib.evaluation.queries import classify_route, hill_queries
    from dgt_lib.logs import heads
    from dgt_lib.navigation.planner import HybridAStar
    from dgt_lib.stages.costmaps import load_model
    from dgt_lib.world.terrain import get_world

    prof = replace(prof, seed=seed)
    robot = load_vehicle(ROBOT)
    log = _log(prof, f"{prof.name}_train{max(RUNS)}_seed{seed}", 100 * seed + 1, max(RUNS))
    held_out = _log(prof, f"{prof.name}_held_out_seed{seed}", 100 * seed + 2, HELD_OUT_RUNS)
    data = study_data(log, held_out, max(RUNS))
    hill = get_world("hill", prof)
    queries = hill_queries(hill, prof.experiments.n_hill, prof.experiments, seed)
    out = {"seed": seed}
    for name, head in (("few-shot", heads.few_shot_head(load_model(prof), data, robot.name)),
                       ("zero-shot", heads.zero_shot_head(prof, robot))):
        maps, cost = heads.world_maps(hill, head, prof, progress=False)
        planner = HybridAStar.for_vehicle(cost, maps.occupancy, maps.grid, robot, prof.planner)
        routes = []
        for q in queries:
            plan = planner.plan(q.start, q.goal)
            routes.append([q.label, classify_route(hill, plan.path) if plan.success else None])
        out[name] = routes
        print(f"seed {seed}, {name}: {routes}", flush=True)
    return out


def hill_table(hills: list[dict]) -> dict:
    """Per head and seed: ascents by Route A, descents by Route B."""
    from dgt_lib.records.study import table

    rows = []
    for name in ("few-shot", "zero-shot"):
        cells = []
        for label, route in (("ascent", "A"), ("descent", "B")):
            counts = [(sum(r == route for lab, r in h[name] if lab == label),
                       sum(lab == label for lab, _ in h[name])) for h in hills]
            cells.append(", ".join(f"{k}/{n}" for k, n in counts))
        rows.append([name, *cells])
    return table(f"Experiment 1's queries planned on the hill for the truck (longest log's "
                 f"few-shot head; seeds {', '.join(str(h['seed']) for h in hills)}; planned, "
                 "not driven)", ["head", "ascents by Route A", "descents by Route B"], rows)


def tables(scores: list[dict]) -> dict[str, dict]:
    """Held-out MAE per log length, mean ± 95 % t-interval over the seeds, and per seed."""
    from dgt_lib.records.study import table

    seeds = [s["seed"] for s in scores]
    mean_rows, seed_rows = [], []
    for i, n_runs in enumerate(RUNS):
        rows = [s["rows"][i] for s in scores]
        cells = [str(n_runs), "{:.1f}".format(np.mean([r["minutes"] for r in rows])),
                 "{:.0f}".format(np.mean([r["patches"] for r in rows]))]
        for h in HEADS:
            m, half = interval([r["mae"][h] for r in rows])
            cells.append(f"{m:.3f} ± {half:.3f}" if np.isfinite(half) else f"{m:.3f}")
        mean_rows.append(cells)
        for r, s in zip(rows, seeds, strict=True):
            best = min(HEADS, key=lambda h: r["mae"][h])
            seed_rows.append([str(n_runs), str(s), f"{r['minutes']:.1f}",
                              *(f"{r['mae'][h]:.3f}" for h in HEADS), best])
    return {
        "minutes": table("Held-out MAE of L̂ for a robot never trained on, by the length of "
                         "its drive log (mean ± 95 % t-interval over the seeds)",
                         ["runs", "labelled minutes", "patches", *HEADS], mean_rows),
        "per_seed": table("Held-out MAE per seed, and the closest head",
                          ["runs", "seed", "labelled minutes", *HEADS, "closest"], seed_rows)}


def figure(scores: list[dict], path: Path) -> None:
    """Held-out MAE against the log's labelled minutes, one line per head (means over the
    seeds; each seed's value as a dot)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 3.6), constrained_layout=True)
    for head, style in zip(HEADS, ("k:", "C0-", "C2-", "C3--"), strict=True):
        per_seed = np.array([[r["mae"][head] for r in s["rows"]] for s in scores])
        minutes = np.array([[r["minutes"] for r in s["rows"]] for s in scores])
        ax.plot(minutes.mean(axis=0), per_seed.mean(axis=0), style, marker="o", label=head)
        ax.plot(minutes.ravel(), per_seed.ravel(), style[:2], marker=".", ls="none", alpha=0.4)
    ax.set_xscale("log")
    ax.set_xlabel("labelled minutes of the robot's drive log (1, 3, 10, 30 runs)")
    ax.set_ylabel("held-out MAE of L̂")
    ax.set_ylim(bottom=0)
    ax.set_title(f"my_truck, never trained on ({len(scores)} seeds)", fontsize=10)
    ax.legend(fontsize=8)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"figure: {path}")


def main() -> None:
    study = Study("log_minutes", __doc__, profile="demo", seeds=3)
    study.parser.add_argument("--stored", action="store_true",
                              help="only the tables of the stored scores")
    study.parser.add_argument("--hill", action="store_true",
                              help="also plan Experiment 1's queries on the hill per seed")
    study.parser.add_argument("--figure", type=Path, default=None,
                              help="figure path (default: in the scores' folder)")
    args = study.parse()
    prof = get_profile(args.profile)
    folder = artifacts.data_root() / "studies" / "log_minutes" / args.profile
    scores = []
    for seed in study.seeds:
        path = folder / f"seed{seed}.json"
        if not path.exists() and not args.stored:
            write_scores(path, score_seed(prof, seed))
        if path.exists():
            scores.append(json.loads(path.read_text()))
    if not scores:
        raise SystemExit(f"no stored scores in {folder}")
    hills = []
    for seed in study.seeds if args.hill else ():
        path = folder / f"seed{seed}_hill.json"
        if not path.exists() and not args.stored:
            write_scores(path, hill_routes(prof, seed))
        if path.exists():
            hills.append(json.loads(path.read_text()))
    figure(scores, args.figure or folder / "log_minutes.png")
    study.finish(tables(scores) | ({"hill": hill_table(hills)} if hills else {}),
                 seeds=[s["seed"] for s in scores])


if __name__ == "__main__":
    main()
