"""Stage ``ground_truth``: the measured directional locomotion L* of every vehicle an
experiment uses on the hill, ridge and eval worlds, and every method's costmap scored
against it (:mod:`dgt_lib.evaluation.ground_truth`, :mod:`dgt_lib.evaluation.accuracy`).

**Cached once per profile, not per seed.** L* depends on the world, the vehicle, the
physics and the drive's settings — not on the run seed, which changes the episodes, the
data split, the weights and the queries but no world (``get_world`` ignores it) and no
drive (the cells come from ``GroundTruthConfig.seed``, the drives are deterministic). So
``data/<profile>/ground_truth/<world>_<vehicle>.npz`` is measured once and every seed's
costmaps are scored against the same reference, which also makes the seeds comparable.
The score depends on the seed's costmaps, so it is cached per seed
(``data/<profile>/seed-<s>/accuracy/costmaps.json``, with ``results/accuracy.md``).

The drives run through :func:`~dgt_lib.core.executors.run_jobs` (a process pool of
``profile.workers``, or any executor passed in) with a progress bar; each finished drive is
appended at once to the pair's journal ``ground_truth/<world>_<vehicle>.<hash>.journal``,
so Ctrl-C loses only the drives in flight and the same command resumes.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor
from pathlib import Path

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import Profile, as_profile
from dgt_lib.core.executors import run_jobs
from dgt_lib.core.faults import report_writes
from dgt_lib.core.geometry import heading_bins
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation import accuracy
from dgt_lib.evaluation.ground_truth import GroundTruth, drive_job, sample_cells
from dgt_lib.evaluation.journal import Journal, read_journal
from dgt_lib.mapping.methods import METHODS
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.perception.locomotion import MAX_ANGULAR_RATE_DPS
from dgt_lib.stages.costmaps import EXPERIMENT_VEHICLES, ensure_tau_s, ensure_world_costmaps
from dgt_lib.stages.output import StageOutput
from dgt_lib.stages.paths import cache_dir, data_dir, profile_root, results_dir
from dgt_lib.world.mujoco_model import PHYSICS
from dgt_lib.world.terrain import get_world

GROUND_TRUTH_FORMAT = 3
"""Version of the ground truth's layout and drive rule (part of its cache key). 2: a stuck
sample reads the L of a standing vehicle, not of its run's last second; 3: stuck means
the cell under the vehicle (half its length), not within the patch (4.4 m)."""
GROUND_TRUTH_WORLDS: tuple[str, ...] = ("hill", "ridge", "eval")
COLLECT_FIELDS: tuple[str, ...] = ("speed_mps", "immobilized_limit_s")
"""The :class:`~dgt_lib.core.config.CollectConfig` fields a drive uses: the commanded
speed and when a stall ends it; what counts as a glitch
(:data:`~dgt_lib.perception.locomotion.MAX_ANGULAR_RATE_DPS`) is in the key beside them, under
the name it had as a collection setting."""
ACCURACY_FORMAT = 3
"""Version of the scores' layout (part of their cache key). 2: multi-task against
single-task by a paired test on the same samples; 3: and by at least MIN_MAE_DIFFERENCE."""
ACCURACY_RELPATH = "accuracy/costmaps.json"
"""The seed's scores, under its data directory."""


def ground_truth_pairs(worlds: Sequence[str] = GROUND_TRUTH_WORLDS) -> list[tuple[str, str]]:
    """(world, vehicle) of every vehicle whose costmaps the experiments build on a world."""
    return [(w, v) for w in worlds for v in EXPERIMENT_VEHICLES[w]]


def ground_truth_relpath(world: str, vehicle: str | VehicleSpec) -> str:
    """``ground_truth/<world>_<vehicle>.npz`` under ``data/<profile>/`` (not a seed's)."""
    return f"ground_truth/{world}_{get_vehicle(vehicle).name}.npz"


def ground_truth_config(world: str, vehicle: str | VehicleSpec, prof: Profile) -> dict[str, object]:
    """What one pair's ground truth depends on (its cache key): no run seed."""
    return {"stage": "ground_truth", "format": GROUND_TRUTH_FORMAT, "world": world,
            "worlds": prof.worlds, "vehicle": get_vehicle(vehicle),
            "ground_truth": prof.ground_truth, "n_headings": prof.costmap.n_headings,
            "collect": {**{f: getattr(prof.collect, f) for f in COLLECT_FIELDS},
                        "max_angular_rate_dps": MAX_ANGULAR_RATE_DPS},
            "physics": PHYSICS}


def _journal_path(world: str, vehicle: str | VehicleSpec, prof: Profile) -> Path:
    digest = artifacts.config_hash(ground_truth_config(world, vehicle, prof))
    stem = ground_truth_relpath(world, vehicle).removesuffix(".npz")
    return profile_root(prof) / f"{stem}.{digest}.journal"


def ensure_ground_truths(pairs: Sequence[tuple[str, str | VehicleSpec]] | None = None,
                         profile: Profile | str | None = None, *,
                         executor: Executor | None = None, progress: bool = True
                         ) -> dict[tuple[str, str | VehicleSpec], GroundTruth]:
    """The ground truth of every (world, vehicle) of ``pairs`` (default
    :func:`ground_truth_pairs`), loaded from ``data/<profile>/ground_truth/`` or measured:
    ``profile.ground_truth.cells`` cells per world × K headings, every missing drive in
    one pool (``executor``, default ``profile.workers`` processes) with one progress bar,
    each journaled as it ends (a rerun resumes)."""
    prof = as_profile(profile)
    pairs = list(pairs or ground_truth_pairs())
    k = prof.costmap.n_headings
    thetas = heading_bins(k)
    out: dict[tuple[str, str], GroundTruth] = {}
    todo: dict[tuple[str, str | VehicleSpec], tuple[np.ndarray, np.ndarray, dict]] = {}
    for w, v in pairs:
        rel, cfg = ground_truth_relpath(w, v), ground_truth_config(w, v, prof)
        if artifacts.is_fresh(rel, cfg, profile=prof.name):
            try:
                out[(w, v)] = GroundTruth.from_arrays(
                    artifacts.load(profile_root(prof) / rel))
                continue
            except Exception:  # noqa: BLE001 - unreadable: measure it again
                pass
        cells, stratum = sample_cells(get_world(w, prof), prof.ground_truth)
        done = read_journal(_journal_path(w, v, prof), key=lambda r: (r["i"], r["k"]))
        todo[(w, v)] = (cells, stratum, done)
    jobs, where = [], {}
    for (w, v), (cells, _, done) in todo.items():
        for i, (x, y) in enumerate(cells):
            for j, theta in enumerate(thetas):
                if (i, j) not in done:
                    job = (prof, w, v, float(x), float(y), float(theta))
                    jobs.append(job)
                    where[job] = ((w, v), i, j)
    journals = {pair: Journal(_journal_path(*pair, prof))
                for pair in {where[job][0] for job in jobs}}
    n_done = sum(len(d) for _, _, d in todo.values())

    def keep(job: tuple, result: dict) -> None:
        pair, i, j = where[job]
        record = {"i": i, "k": j, **result}
        journals[pair].append(record)
        todo[pair][2][(i, j)] = record

    try:
        run_jobs(drive_job, jobs, executor=executor, workers=prof.workers, on_result=keep,
                 progress=progress, desc=f"ground truth ({prof.name})", unit="drive",
                 initial=n_done, total=n_done + len(jobs))
    finally:
        for journal in journals.values():
            journal.close()
    for (w, v), (cells, stratum, done) in todo.items():
        name = get_vehicle(v).name
        gt = GroundTruth.from_drives(w, name, cells, stratum, k, done)
        artifacts.ensure(ground_truth_relpath(w, v), ground_truth_config(w, v, prof),
                         gt.to_arrays, profile=prof.name)
        for stale in (profile_root(prof) / "ground_truth").glob(f"{w}_{name}.*.journal"):
            stale.unlink(missing_ok=True)  # done, or another configuration's
        out[(w, v)] = gt
    return {pair: out[pair] for pair in pairs}


def ensure_ground_truth(world: str, vehicle: str | VehicleSpec,
                        profile: Profile | str | None = None, *,
                        executor: Executor | None = None, progress: bool = True
                        ) -> GroundTruth:
    """The ground truth of one vehicle on one world (see :func:`ensure_ground_truths`):
    a named vehicle or any :class:`~dgt_lib.core.vehicle_spec.VehicleSpec` (a robot's own
    file), stored under its name."""
    return ensure_ground_truths([(world, vehicle)], profile, executor=executor,
                                progress=progress)[(world, vehicle)]


# ----------------------------------------------------------------------------- accuracy


def score_world(world: str, truths: dict[tuple[str, str], GroundTruth],
                profile: Profile | str | None = None, *,
                methods: Sequence[str] = METHODS, progress: bool = True
                ) -> tuple[list[dict], dict[tuple[str, str, str], tuple[np.ndarray, np.ndarray]]]:
    """Every method's costmap on ``world`` against the ground truth of each of its vehicles
    in ``truths``, on the measured samples of cells the occupancy map marks free.

    Returns the rows — ``world``, ``vehicle``, ``method``, ``excluded`` (measured samples
    on occupied or unobserved cells) and :func:`~dgt_lib.evaluation.accuracy.
    costmap_accuracy` — and the scored samples {(world, vehicle, method): (C (n,), C*
    (n,))}, the same samples in the same order for every method."""
    prof = as_profile(profile)
    vehicles = tuple(v for w, v in truths if w == world)
    maps = ensure_world_costmaps(world, vehicles, prof, methods=tuple(methods),
                                 progress=progress)
    rows, samples = [], {}
    for v in vehicles:
        for m in methods:
            scores, samples[(world, v, m)] = score_costmap(maps.costmap(m, v),
                                                           truths[(world, v)], maps, prof)
            rows.append({"world": world, "vehicle": v, "method": m, **scores})
    return rows, samples


def score_costmap(costmap: np.ndarray, gt: GroundTruth, maps: WorldMaps, prof: Profile
                  ) -> tuple[dict, tuple[np.ndarray, np.ndarray]]:
    """One costmap (K, H, W) on ``maps``' grid against one ground truth, on the measured
    samples of cells the occupancy map marks free: ``excluded`` (measured samples on
    occupied or unobserved cells) with :func:`~dgt_lib.evaluation.accuracy.costmap_accuracy`,
    and the scored samples (C (n,), C* (n,))."""
    free = accuracy.free_cells(maps.occupancy, maps.grid, gt.cells)[:, None]
    valid = gt.measured & free
    cost = accuracy.cost_at(costmap, maps.grid, gt.cells, prof.costmap.n_headings)
    scores = {"excluded": int((gt.measured & ~free).sum()),
              **accuracy.costmap_accuracy(gt.cost, cost, valid,
                                          prof.ground_truth.contrast_threshold)}
    return scores, (cost[valid], gt.cost[valid])


def _costmap_digests(prof: Profile, worlds: Sequence[str]) -> dict[str, str]:
    """The stored digests of the seed's costmap files on ``worlds`` and of τ_s."""
    root = data_dir(prof)
    rels = [p.relative_to(root).as_posix() for w in worlds
            for p in sorted((root / "costmaps" / w).glob("*.npz"))]
    rels.append("occupancy/tau_s.json")
    return {rel: artifacts.stored_digest(rel, profile=cache_dir(prof)) for rel in rels}


def ensure_costmap_accuracy(profile: Profile | str | None = None, *,
                            executor: Executor | None = None, progress: bool = True) -> dict:
    """Every method's accuracy against the ground truth on the hill, ridge and eval worlds
    for the profile's run seed (:func:`score_world`), cached as ``accuracy/costmaps.json``
    and written as ``results/accuracy.md``. Returns ``{"rows": [...], "multitask": [...],
    "ground_truth": {"world/vehicle": summary line}}``: a row per (world, vehicle,
    method), multi-task against single-task per vehicle
    (:func:`~dgt_lib.evaluation.accuracy.multitask_comparisons`), and how the drives
    ended."""
    prof = as_profile(profile)
    truths = ensure_ground_truths(None, prof, executor=executor, progress=progress)
    for w in GROUND_TRUTH_WORLDS:  # build (or load) the maps first: their digests key the score
        ensure_world_costmaps(w, EXPERIMENT_VEHICLES[w], prof, progress=progress)
    ensure_tau_s(prof)
    config = {"stage": "accuracy", "format": ACCURACY_FORMAT, "methods": METHODS,
              "threshold": prof.ground_truth.contrast_threshold,
              "ground_truth": {f"{w}/{v}": artifacts.stored_digest(ground_truth_relpath(w, v),
                                                                   profile=prof.name)
                               for w, v in truths},
              "costmaps": _costmap_digests(prof, GROUND_TRUTH_WORLDS)}

    def build() -> dict:
        rows, samples = [], {}
        for w in GROUND_TRUTH_WORLDS:
            r, s = score_world(w, truths, prof, progress=progress)
            rows += r
            samples.update(s)
        return {"rows": rows, "multitask": accuracy.multitask_comparisons(samples),
                "ground_truth": {f"{w}/{v}": gt.summary() for (w, v), gt in truths.items()}}

    result = artifacts.ensure(ACCURACY_RELPATH, config, build, profile=cache_dir(prof))
    out = results_dir(prof)
    with report_writes("results/accuracy.md"):
        out.mkdir(parents=True, exist_ok=True)
        (out / "accuracy.md").write_text(accuracy_markdown(result))
    return result


def cached_costmap_accuracy(profile: Profile | str | None) -> dict | None:
    """The seed's stored accuracy (``accuracy/costmaps.json``) if the stage has run, else
    None (nothing is built): what the results report prints."""
    path = data_dir(profile) / ACCURACY_RELPATH
    return artifacts.load(path) if path.exists() else None


def accuracy_markdown(result: dict) -> str:
    """The accuracy tables of one seed as markdown: the multi-task vs single-task summary,
    every (world, vehicle, method), and how each ground truth's drives ended."""
    return "\n".join([
        "**Multi-task vs single-task per vehicle** (Claim 4 without the closed loop; the same "
        "samples for both, p of a Wilcoxon signed-rank test on their absolute errors):", "",
        accuracy.multitask_table(result["multitask"]),
        "**Every method** (cost C = 1 − L̂ against the measured C* = 1 − L*; contrast over "
        "opposite headings whose C* differs by > 0.3):", "",
        accuracy.accuracy_table(result["rows"]),
        "**Ground truth** (drives through each sampled cell at the K headings):", "",
        *[f"- {line}" for line in result["ground_truth"].values()], ""])


def stage_ground_truth(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: the ground truth (once per profile) and every method's
    accuracy against it (per seed)."""
    prof = as_profile(profile)
    result = ensure_costmap_accuracy(prof)
    parts = [f"{c['vehicle']}: MAE multi-task {c['mae_a']:.3f} / single-task "
             f"{c['mae_b']:.3f} (closer: {c['closer']})" for c in result["multitask"]]
    measured = "; ".join(result["ground_truth"].values())
    return StageOutput([profile_root(prof) / "ground_truth", data_dir(prof) / ACCURACY_RELPATH,
                        results_dir(prof) / "accuracy.md"],
                       "; ".join(parts) + f" — {measured}")
