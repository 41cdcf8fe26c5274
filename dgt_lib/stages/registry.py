"""The stages of ``dgt reproduce``, in pipeline order (docs/stages.md).

A stage is a named, cached callable ``run(profile) -> StageOutput``: it goes through the
artifact cache (``dgt_lib.core.artifacts.ensure``), so a second run reuses what the first
wrote. Each imports its module when called, so ``dgt --help`` stays fast and a stage's
heavy imports are paid only when it runs. A stage with ``report`` set has its figures,
tables and recordings written by the top level (:func:`dgt_lib.app.report.report_stage`).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

from dgt_lib.core.config import Profile
from dgt_lib.stages.output import StageOutput


@dataclass(frozen=True)
class Stage:
    name: str
    run: Callable[[Profile], StageOutput]
    description: str
    kept: str = "what it had finished"
    """What stays in the cache when the stage is stopped by Ctrl-C (said to the user)."""
    report: bool = False
    """Whether ``dgt reproduce`` hands its output to :func:`dgt_lib.app.report.report_stage`."""


def _lazy(target: str) -> Callable[[Profile], StageOutput]:
    """``"module:function"`` as a stage's ``run``: the module is imported when it runs."""
    module, name = target.split(":")

    def run(profile: Profile) -> StageOutput:
        return getattr(importlib.import_module(f"dgt_lib.stages.{module}"), name)(profile)

    run.__name__ = name
    return run


STAGES: list[Stage] = [
    Stage("collect", _lazy("collect:stage_collect"),
          "drive every vehicle on the training world (episodes, sparse RGB-D)",
          "every episode finished so far"),
    Stage("bev", _lazy("collect:stage_bev"),
          "global BEV maps of the training, hill, ridge and eval worlds",
          "every BEV map finished so far"),
    Stage("dataset", _lazy("dataset:stage_dataset"),
          "heading-aligned patches + locomotion labels, split by trajectory",
          "the episodes and BEV maps it needs (the dataset itself is built again)"),
    Stage("train", _lazy("train:stage_train"),
          "multi-task model and one single-task model per vehicle",
          "every model finished so far, and the interrupted one's training up to its last "
          "snapshot (models/<kind>.resume.pt)"),
    Stage("costmaps", _lazy("costmaps:stage_costmaps"),
          "directional costmaps of every method, occupancy maps (τ_s)",
          "every costmap finished so far"),
    Stage("ground_truth", _lazy("ground_truth:stage_ground_truth"),
          "drive every experiment vehicle through sampled cells at the K headings (L*, once "
          "per profile); score each method's costmap against it",
          "every drive finished so far (journaled)"),
    Stage("experiments", _lazy("experiments:stage_experiments"),
          "Experiments 1–3 in closed loop: tables, figures, rerun recordings",
          "every finished experiment and every finished trial (journaled)", report=True),
]


class UnknownStageError(ValueError):
    """A stage name that is not in :data:`STAGES`."""


def stage_names() -> list[str]:
    return [s.name for s in STAGES]


def select(names: list[str] | None) -> list[Stage]:
    """The stages to run, in pipeline order; ``None`` means all. Unknown names are an error."""
    if not names:
        return list(STAGES)
    unknown = [n for n in names if n not in stage_names()]
    if unknown:
        valid = ", ".join(stage_names()) or "(none yet)"
        raise UnknownStageError(f"unknown stage(s) {', '.join(unknown)}; valid stages: {valid}")
    return [s for s in STAGES if s.name in names]
