"""Stage ``experiments``: Experiments 1–3 in closed loop, cached, resumable
(paper: Experiments, Tables I and II).

:func:`ensure_experiment` keys an experiment by everything its trials depend on (the
experiment, planner and costmap settings, the seed and the digests of the models and
slope fits), journals every finished trial so an interrupted run resumes, and writes
``results/<name>.md``. :func:`trial_maps` is how trial workers read their costmaps.
The stage's figures, report and recordings are written by the top level
(:func:`dgt_lib.app.report.report_stage`).
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from pathlib import Path

from dgt_lib.core import artifacts
from dgt_lib.core.config import Profile, as_profile, get_profile
from dgt_lib.core.faults import report_writes
from dgt_lib.core.overrides import format_setting
from dgt_lib.evaluation.experiments import EXPERIMENTS, ExperimentResult, run_experiment
from dgt_lib.evaluation.paper import PAPER
from dgt_lib.evaluation.queries import classify_route
from dgt_lib.mapping.methods import METHOD_LABELS
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.stages.costmaps import ensure_world_costmaps
from dgt_lib.stages.output import StageOutput
from dgt_lib.stages.paths import cache_dir, data_dir
from dgt_lib.stages.train import MODEL_KINDS, model_relpath
from dgt_lib.world.mujoco_model import PHYSICS
from dgt_lib.world.terrain import get_world


@lru_cache(maxsize=16)
def trial_maps(world: str, method: str, vehicle: str, profile: Profile) -> WorldMaps:
    """The costmap of one (world, method, vehicle) with its occupancy map, from the
    artifact cache (built there first if missing); cached per process."""
    return ensure_world_costmaps(world, (vehicle,), profile, methods=(method,),
                                 progress=False)


def _model_digests(prof: Profile) -> dict[str, str | None]:
    """The stored digests of every model and of the slope fits (None where missing)."""
    out: dict[str, str | None] = {}
    for kind, rel in [(k, model_relpath(k, prof.train.inputs)) for k in MODEL_KINDS] + [
            ("slope", "baselines/slope_models.json")]:
        try:
            out[kind] = artifacts.stored_digest(rel, profile=cache_dir(prof))
        except FileNotFoundError:
            out[kind] = None
    return out


EXPERIMENT_FORMAT = 1
"""The version of a stored experiment's trials: bumped by any change that alters them."""


def experiment_config(name: str, prof: Profile) -> dict[str, object]:
    """What an experiment's trials depend on (its cache key; settings at their defaults are
    left out, :mod:`dgt_lib.core.cache_keys`)."""
    experiments = prof.experiments
    if name != "experiment3":  # only Experiment 3 runs on eval_hazard: 1 and 2 never see it
        experiments = replace(experiments, eval_hazard_world=False)
    return {"stage": name, "format": EXPERIMENT_FORMAT, "experiments": experiments,
            "planner": prof.planner, "costmap": prof.costmap, "seed": prof.seed,
            "models": _model_digests(prof), "physics": PHYSICS, "bev": prof.bev,
            "mppi": prof.mppi}


def experiment_stem(name: str, prof: Profile) -> str:
    """The file stem of an experiment's results, ``experiment1``, or for a variant
    ``experiment1.<hash>``: a profile changed by overrides (``--set``, an experiment
    notebook's ``SETTINGS``) whose trials differ from those of the profile's own settings.
    Trying β = 50 then keeps the default results, and going back loads them again."""
    cfg = experiment_config(name, prof)
    if not prof.overrides or cfg == experiment_config(name, get_profile(prof.name).with_(
            seed=prof.seed)):
        return name
    return f"{name}.{artifacts.config_hash(cfg)[:8]}"


def experiment_path(name: str, prof: Profile) -> Path:
    """Where an experiment of ``prof`` (seed and overrides included) is cached."""
    return data_dir(prof) / "experiments" / f"{experiment_stem(name, prof)}.pkl"


def reproduce_command(prof: Profile, stage: str = "experiments") -> str:
    """The ``dgt reproduce`` command that builds ``stage`` for ``prof``, overrides included:
    what a study prints for a result it does not find cached."""
    sets = "".join(f" --set {k}={format_setting(v)}" for k, v in prof.overrides)
    return f"dgt reproduce --profile {prof.name} --seed {prof.seed} --stages {stage}{sets}"


def stored_experiment(name: str, prof: Profile) -> ExperimentResult | None:
    """The cached experiment of ``prof``, or None — never runs one (studies that read
    what ``dgt reproduce`` recorded)."""
    path = experiment_path(name, prof)
    return artifacts.load(path) if path.exists() else None


def ensure_experiment(name: str, profile: Profile | str | None = None, *,
                      progress: bool = True) -> ExperimentResult:
    """An experiment's results through the cache (``experiments/<stem>.pkl``,
    :func:`experiment_stem`), with a markdown report at ``results/<stem>.md``. Every
    finished trial is journaled in ``experiments/<name>.<hash>.trials.pkl`` until the
    experiment is complete, so an interrupted run resumes."""
    prof = as_profile(profile)
    cfg = experiment_config(name, prof)
    stem = experiment_stem(name, prof)
    out = data_dir(prof)
    journal = out / "experiments" / f"{name}.{artifacts.config_hash(cfg)}.trials.pkl"
    result = artifacts.ensure(f"experiments/{stem}.pkl", cfg,
                              lambda: run_experiment(name, prof, load_maps=trial_maps,
                                                     progress=progress, journal=journal),
                              profile=cache_dir(prof))
    for stale in journal.parent.glob(f"{name}.*.trials.pkl"):  # done, or another config's
        stale.unlink(missing_ok=True)
    world = get_world(result.world, prof)
    for r in result.results:  # routes follow the current classification rule
        r.route = classify_route(world, r.path)
    with report_writes(f"results/{stem}.md"):
        (out / "results").mkdir(parents=True, exist_ok=True)
        (out / "results" / f"{stem}.md").write_text(result.markdown(PAPER.get(name)))
    return result


def stage_experiments(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: Experiments 1–3, each with its table in ``results/``; the
    results (``value``) go to the report step."""
    prof = as_profile(profile)
    paths, parts, results = [], [], []
    for name in EXPERIMENTS:
        res = ensure_experiment(name, prof)
        results.append(res)
        paths.append(data_dir(prof) / "results" / f"{experiment_stem(name, prof)}.md")
        counts = ", ".join(f"{METHOD_LABELS[m]} {k}/{n}" for m, (k, n) in res.counts().items())
        parts.append(f"{name}: {counts}")
    return StageOutput(paths, "; ".join(parts), value=results)
