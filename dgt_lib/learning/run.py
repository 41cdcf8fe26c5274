"""The bookkeeping around :func:`~dgt_lib.learning.training.fit`: progress bars, a live
per-batch callback, the best model's checkpoint, snapshots and resume, Ctrl-C, the final
test metrics and the collapsed-head check.

:func:`train_network` trains any network of the :class:`~dgt_lib.learning.training.MultiHeadNet`
kind (a new :class:`~dgt_lib.learning.model.DGTNet` from :func:`train_model`, or another
network its caller built) and
returns its :class:`~dgt_lib.learning.checkpoints.TrainResult`. With ``snapshot_path`` the
training is saved after an epoch (:mod:`dgt_lib.learning.resume`) and the next call resumes
after it: an interrupt or a crash costs at most ``snapshot_every_s`` and an epoch.
"""

from __future__ import annotations

import copy
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from dgt_lib.core.config import TrainConfig
from dgt_lib.learning.checkpoints import TrainResult, save_checkpoint
from dgt_lib.learning.model import DGTNet
from dgt_lib.learning.resume import TrainingState, load_training_state, training_identity
from dgt_lib.learning.scarcity import keep_runs
from dgt_lib.learning.training import (
    FitHooks,
    FitState,
    MultiHeadNet,
    TrainingSet,
    channel_statistics,
    collapsed_heads,
    evaluate,
    fit,
    head_prior,
    resolve_device,
)
from dgt_lib.perception.dataset import TEST, PatchDataset


class Snapshots:
    """A training's snapshot file: resumed at the start if it is of this same training
    (``identity``), rewritten after an epoch once ``every_s`` seconds have passed."""

    def __init__(self, path: str | Path, identity: str, every_s: float, name: str) -> None:
        self.path, self.identity, self.every_s, self.name = Path(path), identity, every_s, name
        self.saved_epoch = 0  # the last epoch in the file
        self.last = time.perf_counter()

    def resume(self, model: torch.nn.Module, optimizer: torch.optim.Optimizer,
               rng: np.random.Generator) -> FitState:
        """The training's state from the file (weights, Adam moments, generators restored),
        or a fresh :class:`FitState` when there is none of this training."""
        state, why = load_training_state(self.path, self.identity)
        if state is None:
            if why != "missing":
                tqdm.write(f"[dgt] {self.name}: not resuming the snapshot {self.path}, {why}; "
                           "training from the start")
            return FitState()
        best_state = state.restore(model, optimizer, rng)
        self.saved_epoch = state.epoch
        tqdm.write(f"[dgt] {self.name}: resuming after epoch {state.epoch} ({self.path})")
        return FitState(state.epoch, state.step_count, state.history, state.best_epoch,
                        state.best_val, best_state)

    def maybe_save(self, state: FitState, model: torch.nn.Module,
                   optimizer: torch.optim.Optimizer, rng: np.random.Generator) -> None:
        if time.perf_counter() - self.last >= self.every_s:
            TrainingState.capture(self.identity, state.epoch, state.step_count, model, optimizer,
                                  rng, state.history, state.best_epoch, state.best_val,
                                  state.best_state).save(self.path)
            self.saved_epoch, self.last = state.epoch, time.perf_counter()

    def tell_interrupted(self) -> None:
        if self.saved_epoch:
            n = self.saved_epoch
            epochs = "epoch 1 is" if n == 1 else f"epochs 1–{n} are"
            tqdm.write(f"[dgt] {self.name}: {epochs} saved in {self.path}; "
                       f"the next run resumes after epoch {n}")


@dataclass
class RunHooks(FitHooks):
    """Progress bars, the caller's ``on_batch_end``, the best model's checkpoint and the
    snapshots, after each batch and epoch of :func:`fit`."""

    name: str
    cfg: TrainConfig
    seed: int
    model: torch.nn.Module
    optimizer: torch.optim.Optimizer
    rng: np.random.Generator
    progress: bool = True
    on_batch_end: Callable[[int, int, float], None] | None = None
    checkpoint_path: str | Path | None = None
    snapshots: Snapshots | None = None
    first_epoch: int = 0
    batch_bar: Any = None

    def __post_init__(self) -> None:
        self.epochs_bar = tqdm(desc=f"train {self.name}", unit="epoch", initial=self.first_epoch,
                               total=self.cfg.epochs, disable=not self.progress)

    def epoch_start(self, epoch: int, n_batches: int) -> None:
        self.batch_bar = tqdm(total=n_batches, desc=f"epoch {epoch}", unit="batch",
                              leave=False, disable=not self.progress)

    def step(self, epoch: int, i: int, loss: float, mean: float) -> None:
        self.batch_bar.update(1)
        self.batch_bar.set_postfix(loss=f"{mean:.4f}")
        if self.on_batch_end is not None:
            self.on_batch_end(epoch, i, loss)

    def epoch_end(self, state: FitState, improved: bool) -> None:
        self.batch_bar.close()
        if improved and self.checkpoint_path is not None:  # the model holds the best weights
            save_checkpoint(self.checkpoint_path, TrainResult(
                self.model, copy.deepcopy(state.history), state.best_epoch, {}, False, self.cfg,
                self.seed))
        if self.snapshots is not None:
            self.snapshots.maybe_save(state, self.model, self.optimizer, self.rng)
        last = state.history[-1]
        self.epochs_bar.update(1)
        self.epochs_bar.set_postfix(train=f"{last['train_loss']:.4f}",
                                    val=f"{last['val_loss']:.4f}", best=state.best_epoch)

    def close(self) -> None:
        if self.batch_bar is not None:
            self.batch_bar.close()
        self.epochs_bar.close()


def train_network(
    model: MultiHeadNet,
    data: TrainingSet,
    cfg: TrainConfig,
    *,
    seed: int = 0,
    device: str | torch.device | None = None,
    progress: bool = True,
    checkpoint_path: str | Path | None = None,
    on_batch_end: Callable[[int, int, float], None] | None = None,
    keep_best_on_interrupt: bool = True,
    snapshot_path: str | Path | None = None,
    snapshot_key: Any = None,
    snapshot_every_s: float = 60.0,
) -> TrainResult:
    """Train ``model`` (heads ``data.vehicles``, input normalisation set) on ``data`` with
    :func:`fit`; keep the epoch ``cfg.selection`` picks and return it with its test metrics.

    Args:
        seed: the batch order and mirror draws (the caller seeds torch before it builds
            the network).
        device: default: a CUDA GPU when present, else the CPU.
        progress: tqdm bars with the live loss.
        checkpoint_path: the best model so far is saved there (``.pt``, atomically,
            :func:`~dgt_lib.learning.checkpoints.save_checkpoint`: a DGTNet) each time the
            validation loss improves, and the result at the end.
        on_batch_end: called as ``on_batch_end(epoch, step, loss)`` after every step.
        keep_best_on_interrupt: Ctrl-C (KeyboardInterrupt) ends training after the last
            finished epoch, keeping the best weights so far (``interrupted=True``; re-raised
            before the first epoch ends). False: re-raised at once, nothing evaluated or saved.
        snapshot_path: the training's state after an epoch is saved there (``.pt``,
            :class:`~dgt_lib.learning.resume.TrainingState`) at most every
            ``snapshot_every_s`` seconds [s]; a snapshot there of this same training
            (settings, vehicles, seed, network, data, ``snapshot_key``) is resumed, to the
            weights of a training never stopped (bit for bit on the CPU). The caller deletes
            the file once the result is stored (:func:`~dgt_lib.stages.train.ensure_model`).
        snapshot_key: anything else that identifies this training (JSON-able).
    """
    vehicles = data.vehicles
    if tuple(model.vehicles) != vehicles:
        raise ValueError(f"the model's heads {model.vehicles} are not the vehicles {vehicles}")
    device = resolve_device(device)
    rng = np.random.default_rng(seed)
    if cfg.head_init == "prior":
        model.init_heads(head_prior(data.dataset, data.train_index, vehicles,
                                    data.codes))
    live_taps = cfg.conv_taps == "live" and hasattr(model, "use_live_taps")
    if live_taps:
        model.use_live_taps()
    model.to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=cfg.learning_rate)
    name = "multi-task" if len(vehicles) > 1 else f"single-task {vehicles[0]}"
    snapshots, state = None, FitState()
    if snapshot_path is not None:
        ds = data.dataset
        identity = training_identity(cfg, vehicles, seed, model, ds.patches, ds.labels,
                                     data.train_index, data.val_index, snapshot_key)
        snapshots = Snapshots(snapshot_path, identity, snapshot_every_s, name)
        state = snapshots.resume(model, optimizer, rng)
    hooks = RunHooks(name, cfg, seed, model, optimizer, rng, progress, on_batch_end,
                     checkpoint_path, snapshots, first_epoch=state.epoch)
    interrupted = False
    try:
        fit(model, optimizer, data, cfg, rng, device, state, hooks)
    except KeyboardInterrupt:
        if snapshots is not None:
            snapshots.tell_interrupted()
        if state.best_state is None or not keep_best_on_interrupt:
            raise
        interrupted = True
        tqdm.write(f"[dgt] training interrupted: keeping epoch {state.best_epoch} "
                   f"(val loss {state.best_val:.4f})")
    finally:
        hooks.close()
        if live_taps:
            model.use_live_taps(False)  # the trained network evaluates with its full kernels
    return _result(model, data, cfg, seed, state, interrupted, name, checkpoint_path)


def _result(model: MultiHeadNet, data: TrainingSet, cfg: TrainConfig, seed: int,
            state: FitState, interrupted: bool, name: str,
            checkpoint_path: str | Path | None) -> TrainResult:
    """The best epoch's weights in ``model`` (eval mode), its test metrics, a warning per
    collapsed head, saved to ``checkpoint_path`` if given."""
    if state.best_state is None:
        raise RuntimeError(f"training {name} diverged: validation loss "
                           f"{[h['val_loss'] for h in state.history]}; try a lower learning rate")
    model.load_state_dict(state.best_state)
    model.eval()
    ds = data.dataset
    metrics = evaluate(model, ds.subset(data.chosen & (ds.split == TEST)),
                       codes=data.codes)
    for v in collapsed_heads(metrics):
        m = metrics[v]
        warnings.warn(f"{name}: the {v} head predicts a near-constant L̂ on the test set "
                      f"(std {m['pred_std']:.1e} against the labels' {m['label_std']:.2f}): "
                      "it learned next to nothing (too few epochs, or a saturated sigmoid)",
                      stacklevel=4)
    result = TrainResult(model, state.history, state.best_epoch, metrics, interrupted, cfg, seed)
    if checkpoint_path is not None:
        save_checkpoint(checkpoint_path, result)
    return result


def train_model(
    dataset: PatchDataset,
    cfg: TrainConfig,
    *,
    vehicles: tuple[str, ...] | list[str] | str | None = None,
    seed: int = 0,
    device: str | torch.device | None = None,
    progress: bool = True,
    rgb_weights: str | Path | None = None,
    **run: Any,
) -> TrainResult:
    """Train a new :class:`DGTNet` on ``dataset`` with Adam and the masked loss (:func:`fit`
    inside :func:`train_network`); keep the epoch ``cfg.selection``
    picks. Returns its :class:`TrainResult` (test-split metrics per vehicle).

    vehicles: None = multi-task on every vehicle (one head each); a tuple of names (e.g.
    ``("vw_van",)``) trains on those vehicles' samples only (single-task). seed: weight
    initialisation and batch order (same seed, same weights on the CPU with the same
    thread count). rgb_weights: torchvision's ImageNet ResNet-18 file for the RGB branch
    (width 64). ``run``: the run's bookkeeping (checkpoint, snapshots and resume, Ctrl-C,
    live callback), as :func:`train_network` takes it. With ``cfg.scarce_vehicle`` only
    a fraction of that vehicle's training runs is used (:func:`~dgt_lib.learning.scarcity.
    keep_runs`, drawn by ``seed``).
    """
    if cfg.scarce_vehicle != "none":
        dataset = keep_runs(dataset, cfg.scarce_vehicle, cfg.scarce_fraction, seed)
    data = TrainingSet.select(dataset, vehicles, cfg)
    device = resolve_device(device)
    torch.manual_seed(seed)
    model = DGTNet(data.vehicles, width=cfg.width, fc_hidden=cfg.fc_hidden,
                   rgb_weights=rgb_weights, inputs=cfg.inputs)
    model.set_normalization(*channel_statistics(dataset.patches, data.train_index))
    return train_network(model, data, cfg, seed=seed, device=device, progress=progress, **run)
