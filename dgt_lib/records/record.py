"""One seed's run record: ``results/summary.json`` in the seed's data directory.

:func:`seed_record` builds it from the seed's experiments and the cached model and
accuracy results, headed by :func:`~dgt_lib.records.provenance.provenance` and the
paper's claims checked in that seed (:data:`dgt_lib.evaluation.seeds.CLAIMS`).
:func:`seed_summaries` reads the profile's records back; :mod:`.publish` copies them into
``docs/runs/`` with the stages' wall times.
"""

from __future__ import annotations

import json
from pathlib import Path

from dgt_lib.core.config import Profile, as_profile
from dgt_lib.core.overrides import format_setting
from dgt_lib.evaluation import seeds
from dgt_lib.evaluation.experiments import ExperimentResult
from dgt_lib.learning.training import collapsed_heads
from dgt_lib.records.provenance import provenance
from dgt_lib.stages.ground_truth import cached_costmap_accuracy
from dgt_lib.stages.paths import results_dir
from dgt_lib.stages.train import cached_model_metrics

SCHEMA = 1
"""The record format's version: raised when a field changes meaning."""

SUMMARY_NAME = "summary.json"
"""One seed's record, in the seed's results directory
(:func:`~dgt_lib.stages.paths.results_dir`)."""


def claim_checks(summary: dict) -> dict[str, list]:
    """{claim: [count, out of, holds]} of :data:`~dgt_lib.evaluation.seeds.CLAIMS` in one
    seed's summary."""
    out = {}
    for name, (_, count) in seeds.CLAIMS.items():
        k, n = count(summary)
        out[name] = [k, n, seeds.claim_holds(name, k, n)]
    return out


def seed_record(results: list[ExperimentResult], prof: Profile) -> dict:
    """The record of ``prof``'s run seed: provenance, profile, seed, settings changed
    from the profile's, every experiment's counts, routes and failure reasons, the
    models' test metrics and collapsed heads, the costmaps' accuracy against the ground
    truth (None before that stage ran) and the claims checked in this seed."""
    models = cached_model_metrics(prof)
    scores = cached_costmap_accuracy(prof)
    record = {"schema": SCHEMA, **provenance(), "profile": prof.name, "seed": prof.seed,
              "overrides": {k: format_setting(v) for k, v in prof.overrides},
              "experiments": {r.name: seeds.experiment_summary(r) for r in results},
              "models": models,
              "collapsed": {kind: collapsed_heads(m) for kind, m in models.items()},
              "accuracy": None if scores is None else scores["rows"],
              "multitask": None if scores is None else scores["multitask"]}
    record["claims"] = claim_checks(record)
    return record


def write_seed_record(results: list[ExperimentResult], prof: Profile) -> Path:
    """Write :func:`seed_record` to ``results/summary.json`` of the seed; its path."""
    path = results_dir(prof) / SUMMARY_NAME
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(seed_record(results, prof), indent=1, ensure_ascii=False))
    return path


def seed_summaries(profile: Profile | str | None, *, require_all: bool = False) -> list[dict]:
    """The record of each of the profile's seeds that has one (all of them, or a
    FileNotFoundError naming the first missing seed, with ``require_all``)."""
    prof = as_profile(profile)
    records = []
    for p in prof.seed_profiles():
        path = results_dir(p) / SUMMARY_NAME
        if path.exists():
            records.append(json.loads(path.read_text()))
        elif require_all:
            raise FileNotFoundError(f"no results for seed {p.seed} ({path}): run "
                                    f"`dgt reproduce --profile {prof.name}` first")
    return records
