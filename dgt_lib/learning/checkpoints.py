"""Checkpoints of a trained :class:`~dgt_lib.learning.model.DGTNet`: what training
returns (:class:`TrainResult`), and saving / loading it with its architecture, history,
metrics and settings, checked on load.

Importing this module does not import torch (:func:`load_checkpoint` does): the model
cache's key (:data:`CHECKPOINT_VERSION`) is checked by ``dgt plan`` without it."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dgt_lib.core import artifacts
from dgt_lib.core.config import TrainConfig

if TYPE_CHECKING:
    import torch

    from dgt_lib.learning.model import DGTNet

CHECKPOINT_FORMAT = "dgt-kit/DGTNet"


CHECKPOINT_VERSION = 3  # 3: heads start at their prior (TrainConfig.head_init)


class CheckpointError(ValueError):
    """A file or object that is not a DGTNet checkpoint written by :func:`save_checkpoint`."""


@dataclass
class TrainResult:
    """A trained model and how it got there.

    model: the network with the best validation epoch's weights, in eval mode.
    history: one dict per finished epoch: ``epoch`` (1-based), ``train_loss``,
        ``val_loss`` (mean masked squared error), ``seconds``.
    best_epoch: the epoch whose weights ``model`` holds (1-based).
    metrics: test-split metrics per vehicle (see :func:`evaluate`).
    interrupted: True when training stopped on KeyboardInterrupt.
    """

    model: DGTNet
    history: list[dict[str, float]]
    best_epoch: int
    metrics: dict[str, dict[str, float]]
    interrupted: bool = False
    config: TrainConfig | None = None
    seed: int | None = None


def checkpoint_dict(result: TrainResult) -> dict[str, Any]:
    """The checkpoint of a result: architecture, weights (CPU), history, metrics, settings."""
    return {
        "format": CHECKPOINT_FORMAT,
        "version": CHECKPOINT_VERSION,
        "architecture": result.model.architecture(),
        "rgb_pretrained": bool(result.model.rgb_pretrained),
        "state_dict": {k: v.detach().cpu() for k, v in result.model.state_dict().items()},
        "history": result.history,
        "best_epoch": result.best_epoch,
        "metrics": result.metrics,
        "interrupted": result.interrupted,
        "train_config": asdict(result.config) if result.config is not None else None,
        "seed": result.seed,
    }


def prediction_digest(ckpt: dict[str, Any]) -> str:
    """A digest of what determines a checkpoint's predictions: its architecture and
    every tensor of its ``state_dict`` (weights, BatchNorm statistics, the input
    normalisation) — not its history, timings, metrics or settings. Two trainings that
    end with bit-identical weights have the same digest (16 hex digits)."""
    tensors = {name: t.detach().cpu().numpy() for name, t in ckpt["state_dict"].items()}
    return artifacts.config_hash({"architecture": ckpt["architecture"], "state_dict": tensors})


def save_checkpoint(path: str | Path, result: TrainResult) -> Path:
    """Write ``result`` to ``path`` (``.pt``) atomically; returns the path."""
    path = Path(path)
    if path.suffix != ".pt":
        raise ValueError(f"checkpoints are .pt files, got {path}")
    artifacts.save(path, checkpoint_dict(result))
    return path


def load_checkpoint(
    source: str | Path | dict[str, Any],
    *,
    vehicles: tuple[str, ...] | list[str] | None = None,
    architecture: dict[str, Any] | None = None,
    device: str | torch.device = "cpu",
    build: Callable[[dict[str, Any]], DGTNet] | None = None,
) -> TrainResult:
    """Read a checkpoint (a ``.pt`` path or the dict of :func:`checkpoint_dict`).

    ``vehicles`` and ``architecture`` (e.g. ``DGTNet(...).architecture()``) are what
    the caller expects; a checkpoint of another vehicle set or architecture raises
    :class:`~dgt_lib.learning.model.ArchitectureMismatchError` saying what differs. Something
    that is not a DGTNet checkpoint raises :class:`CheckpointError`. ``build``: the
    untrained network of an architecture dict that the weights are loaded into (default a
    DGTNet; a network of another kind, such as
    :func:`~dgt_lib.beyond.conditioned.load_conditioned`'s, passes its own).
    """
    from dgt_lib.learning.model import ArchitectureMismatchError, DGTNet

    where = str(source) if not isinstance(source, dict) else "checkpoint"
    ckpt = artifacts.load(Path(source)) if not isinstance(source, dict) else source
    if not isinstance(ckpt, dict) or ckpt.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{where} is not a {CHECKPOINT_FORMAT} checkpoint")
    if ckpt.get("version") != CHECKPOINT_VERSION:
        raise CheckpointError(f"{where} has checkpoint version {ckpt.get('version')}, "
                              f"this code reads version {CHECKPOINT_VERSION}")
    arch = ckpt["architecture"]
    if vehicles is not None and list(vehicles) != list(arch["vehicles"]):
        raise ArchitectureMismatchError(
            f"{where} has heads for {tuple(arch['vehicles'])}, expected {tuple(vehicles)}")
    if architecture is not None and dict(architecture) != arch:
        diff = {k: (arch.get(k), architecture.get(k)) for k in set(arch) | set(architecture)
                if arch.get(k) != architecture.get(k)}
        raise ArchitectureMismatchError(
            f"{where} has a different architecture (checkpoint, expected): {diff}")
    if build is None and arch.get("name", "DGTNet") != "DGTNet":
        raise ArchitectureMismatchError(
            f"{where} holds a {arch['name']}, not a DGTNet (a ConditionedNet loads with "
            "dgt_lib.beyond.conditioned.load_conditioned)")
    model = (build(arch) if build is not None else
             DGTNet(arch["vehicles"], width=arch["width"], fc_hidden=arch["fc_hidden"],
                    inputs=arch.get("inputs", "rgbd")))
    try:
        model.load_state_dict(ckpt["state_dict"])
    except RuntimeError as exc:
        raise ArchitectureMismatchError(f"{where}: weights do not fit {arch}: {exc}") from exc
    model.rgb_pretrained = bool(ckpt.get("rgb_pretrained", False))
    model.to(device).eval()
    cfg = None
    if ckpt.get("train_config"):  # settings deleted since it was written are left out
        known = {f.name for f in fields(TrainConfig)}
        cfg = TrainConfig(**{k: v for k, v in ckpt["train_config"].items() if k in known})
    return TrainResult(model=model, history=ckpt["history"], best_epoch=ckpt["best_epoch"],
                       metrics=ckpt["metrics"], interrupted=ckpt["interrupted"], config=cfg,
                       seed=ckpt.get("seed"))
