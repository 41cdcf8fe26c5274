"""Resuming an interrupted training: the state of
:func:`~dgt_lib.learning.training.fit` after a finished epoch, saved and resumed by
:func:`~dgt_lib.learning.run.train_network`. With a snapshot, Ctrl-C or a crash costs at
most the time since it (docs/training.md).

A snapshot holds everything the following epochs depend on — the weights and BatchNorm
statistics, Adam's moments, the batch order's random generator (numpy) and torch's, the
step count of the learning-rate schedule, the history, the best epoch and its weights — so
a resumed training makes the same updates as one never stopped, and ends with the same
weights (bit for bit on one machine: ``tests/test_train.py``). It also records what it is a
snapshot *of* (:func:`training_identity`: settings, vehicles, seed, the network's shapes,
the samples and labels, and any key the caller adds); a snapshot of anything else is not
resumed. Written atomically (``artifacts.save``): a crash while writing leaves the
previous epoch's snapshot.
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
import torch

from dgt_lib.core import artifacts
from dgt_lib.core.config import TrainConfig

SNAPSHOT_FORMAT = "dgt-kit/training-snapshot-1"


def training_identity(cfg: TrainConfig, vehicles: tuple[str, ...], seed: int,
                      model: torch.nn.Module, patches: np.ndarray, labels: np.ndarray,
                      train_index: np.ndarray, val_index: np.ndarray,
                      key: Any = None) -> str:
    """A digest of what a training run is: ``cfg``, ``vehicles``, ``seed``, the network's
    class and tensor shapes, every patch and label, the training and validation indices,
    and the caller's ``key`` (e.g. the model cache's configuration). 16 hex digits."""
    h = hashlib.sha256()
    for array in (patches, labels, train_index, val_index):
        h.update(np.ascontiguousarray(array).view(np.uint8).reshape(-1).data)
    shapes = {name: list(t.shape) for name, t in model.state_dict().items()}
    return artifacts.config_hash({"train": asdict(cfg), "vehicles": list(vehicles),
                                  "seed": int(seed), "network": type(model).__name__,
                                  "shapes": shapes, "data": h.hexdigest(), "key": key})


def _cpu_copy(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    return {k: v.detach().to("cpu", copy=True) for k, v in state.items()}


@dataclass
class TrainingState:
    """A training after its epoch ``epoch`` (1-based): see the module docstring.

    best_state: the best epoch's weights, None when that is ``epoch`` itself (then they
    are ``model``; the file is a quarter smaller).
    """

    identity: str
    epoch: int
    step_count: int
    model: dict[str, torch.Tensor]
    optimizer: dict[str, Any]
    numpy_rng: dict[str, Any]
    torch_rng: torch.Tensor
    history: list[dict[str, float]]
    best_epoch: int
    best_val: float
    best_state: dict[str, torch.Tensor] | None

    @classmethod
    def capture(cls, identity: str, epoch: int, step_count: int, model: torch.nn.Module,
                optimizer: torch.optim.Optimizer, rng: np.random.Generator,
                history: list[dict[str, float]], best_epoch: int, best_val: float,
                best_state: dict[str, torch.Tensor] | None) -> TrainingState:
        """The state of a training right after its epoch ``epoch``. Its optimizer state
        refers to the optimizer's own tensors: :meth:`save` it before the next step."""
        return cls(identity=identity, epoch=epoch, step_count=step_count,
                   model=_cpu_copy(model.state_dict()), optimizer=optimizer.state_dict(),
                   numpy_rng=rng.bit_generator.state, torch_rng=torch.get_rng_state(),
                   history=[dict(h) for h in history], best_epoch=best_epoch,
                   best_val=best_val, best_state=None if best_epoch == epoch else best_state)

    def restore(self, model: torch.nn.Module, optimizer: torch.optim.Optimizer,
                rng: np.random.Generator) -> dict[str, torch.Tensor]:
        """Put the snapshot's weights, Adam moments and generators into ``model``,
        ``optimizer`` and ``rng`` (and torch's generator); returns the best epoch's
        weights (CPU)."""
        model.load_state_dict(self.model)
        optimizer.load_state_dict(self.optimizer)  # moves the moments to the model's device
        rng.bit_generator.state = self.numpy_rng
        torch.set_rng_state(self.torch_rng)
        return _cpu_copy(self.model) if self.best_state is None else self.best_state

    def save(self, path: str | Path) -> None:
        """Write the snapshot to ``path`` (``.pt``) atomically."""
        # fields, not dataclasses.asdict: that would deep-copy every tensor first
        artifacts.save(Path(path), {"format": SNAPSHOT_FORMAT,
                                    **{f.name: getattr(self, f.name) for f in fields(self)}})


def load_training_state(path: str | Path, identity: str) -> tuple[TrainingState | None, str]:
    """The snapshot at ``path`` if it is one of the training ``identity``, and why not.

    Returns ``(state, "")``, or ``(None, reason)``: ``"missing"``, ``"unreadable (…)"``, or
    ``"of another training"`` (other settings, data, seed, network or key).
    """
    path = Path(path)
    if not path.exists():
        return None, "missing"
    try:
        raw = artifacts.load(path)
        if not isinstance(raw, dict) or raw.get("format") != SNAPSHOT_FORMAT:
            raise ValueError("not a training snapshot")
        raw.pop("format")
        state = TrainingState(**raw)
    except Exception as exc:  # noqa: BLE001 - any failure to read means start over
        return None, f"unreadable ({type(exc).__name__}: {exc})"
    if state.identity != identity:
        return None, "of another training"
    return state, ""
