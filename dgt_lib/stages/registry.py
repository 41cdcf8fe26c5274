"""The stages of ``dgt reproduce``, in pipeline order.

A stage is a named, cached entry point ``run(profile) -> StageOutput``: it goes
through the artifact cache (``dgt_lib.core.artifacts.ensure``), so a second run
reuses what the first wrote. Issues that build a stage add it to :data:`STAGES`
(keep the data-flow order of docs/ARCHITECTURE.md), saying what stays cached when Ctrl-C stops it.
Entry points are named as ``"module:function"`` strings and imported only when run,
so ``dgt --help`` stays fast and a stage's heavy imports are paid only when it runs.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from dgt_lib.core.config import Profile


@dataclass
class StageOutput:
    """What a stage wrote (paths) and a one-line summary of it."""

    paths: list[Path] = field(default_factory=list)
    summary: str = ""


@dataclass(frozen=True)
class Stage:
    name: str
    entry_point: str  # "dgt_lib.module:function", function(profile) -> StageOutput
    description: str
    kept: str = "what it had finished"
    """What stays in the cache when the stage is stopped by Ctrl-C (said to the user)."""

    def load(self) -> Callable[[Profile], StageOutput]:
        module, _, func = self.entry_point.partition(":")
        return getattr(importlib.import_module(module), func)


STAGES: list[Stage] = [
    Stage("collect", "dgt_lib.stages.collect:stage_collect",
          "drive every vehicle on the training world (episodes, sparse RGB-D)",
          "every episode finished so far"),
    Stage("bev", "dgt_lib.stages.collect:stage_bev",
          "global BEV maps of the training, hill, ridge and eval worlds",
          "every BEV map finished so far"),
    Stage("dataset", "dgt_lib.stages.dataset:stage_dataset",
          "heading-aligned patches + locomotion labels, split by trajectory",
          "the episodes and BEV maps it needs (the dataset itself is built again)"),
    Stage("train", "dgt_lib.stages.train:stage_train",
          "multi-task model and one single-task model per vehicle",
          "every model finished so far, and the interrupted one's training up to its last "
          "snapshot (models/<kind>.resume.pt)"),
    Stage("costmaps", "dgt_lib.stages.costmaps:stage_costmaps",
          "directional costmaps of every method, occupancy maps (τ_s)",
          "every costmap finished so far"),
    Stage("ground_truth", "dgt_lib.stages.ground_truth:stage_ground_truth",
          "drive every experiment vehicle through sampled cells at the K headings (L*, once "
          "per profile); score each method's costmap against it",
          "every drive finished so far (journaled)"),
    Stage("experiments", "dgt_lib.report:stage_experiments",
          "Experiments 1–3 in closed loop: tables, figures, rerun recordings",
          "every finished experiment and every finished trial (journaled)"),
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
