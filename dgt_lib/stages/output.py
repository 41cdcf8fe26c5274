"""What a stage of ``dgt reproduce`` returns (:mod:`dgt_lib.stages.registry`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class StageOutput:
    """What a stage wrote (paths), a one-line summary of it, and what it computed for its
    report step (``value``: the experiments' results, drawn by :mod:`dgt_lib.app.report`)."""

    paths: list[Path] = field(default_factory=list)
    summary: str = ""
    value: object = None
