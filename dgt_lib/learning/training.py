"""Multi-task training of :class:`~dgt_lib.learning.model.DGTNet`: the masked loss, one
epoch of Adam (:func:`train_epoch`), the epochs with model selection (:func:`fit`),
prediction and metrics.

Paper: Multi-Task Learning and Baselines (DGT-Map(ST)). The multi-task model is trained on
every vehicle's patches at once with the masked loss (:func:`masked_loss`): a patch of
vehicle v trains the shared backbone and head v only. The single-task variant is the same
architecture with one head, trained on one vehicle's data. Plain shuffled minibatches over
all training samples (the dataset's vehicle imbalance is kept, as in the paper). Ours,
beyond the paper: heads start at their vehicle's prior (``TrainConfig.head_init``), a
cosine learning rate and
last-epoch selection (``lr_schedule``, ``selection``); why: docs/training.md.

Typical use::

    result = train_model(dataset, profile.train, seed=0)              # multi-task
    single = train_model(dataset, profile.train, vehicles=("vw_van",))
    # cached per profile and seed: dgt_lib.stages.train.ensure_model(profile, dataset, kind)
    L_hat = predict(result.model, patches)                            # (N, n_heads)

The run around :func:`fit` (progress, checkpoints, snapshots and resume, Ctrl-C, test
metrics) is :mod:`dgt_lib.learning.run`.
"""

from __future__ import annotations

import copy
import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np
import torch

from dgt_lib.core.config import VEHICLES, TrainConfig
from dgt_lib.learning.model import N_CHANNELS, DGTNet, centre_heights
from dgt_lib.perception.dataset import TRAIN, VAL, PatchDataset

if TYPE_CHECKING:
    pass

def masked_loss(pred: torch.Tensor, labels: torch.Tensor, head: torch.Tensor) -> torch.Tensor:
    """The multi-task loss of a batch (paper: Multi-Task Learning).

        𝓛(P, v) = ‖L̂_v(P) − L_v(t_P)‖²

    Only the head of the vehicle that collected patch P contributes; the other
    heads' outputs are not used, so they get exactly zero gradient from P.
    pred: (B, n_heads) predictions; labels: (B,) L_v(t_P); head: (B,) int64 column
    of each sample's vehicle. Returns the mean over the batch (a scalar).
    """
    chosen = pred.gather(1, head[:, None]).squeeze(1)  # (B,) L̂_v(P)
    return torch.mean((chosen - labels) ** 2)


def default_device() -> torch.device:
    """The first CUDA GPU when there is one, else the CPU."""
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


def resolve_device(device: str | torch.device | None = None) -> torch.device:
    """A torch device from ``ExecutionConfig.device`` or ``--device``: None or ``"auto"``
    → :func:`default_device`; ``"cpu"``, ``"cuda"``, ``"cuda:1"`` or a
    :class:`torch.device` as given. Asking for CUDA where torch sees no GPU is a
    :class:`ValueError` saying so, not a failure deep inside the first batch."""
    if device is None or device == "auto":
        return default_device()
    dev = torch.device(device)
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device {str(device)!r}: torch {torch.__version__} sees no CUDA GPU "
                         "(use --device auto or cpu)")
    return dev


def learning_rate_at(cfg: TrainConfig, step: int, total_steps: int) -> float:
    """Adam's learning rate at optimiser step ``step`` of ``total_steps`` (0-based).

    ``"constant"``: ``cfg.learning_rate``. ``"cosine"`` (ours)::

        η_t = η₀ · ½ (1 + cos(π t / T))

    from η₀ at the first step to ~0 at the last: late epochs take small steps, so the
    weights settle instead of jumping between minibatch noise (docs/training.md)."""
    if cfg.lr_schedule == "constant":
        return cfg.learning_rate
    return cfg.learning_rate * 0.5 * (1.0 + math.cos(math.pi * step / max(total_steps, 1)))


def _index_batches(index: np.ndarray, batch_size: int) -> list[np.ndarray]:
    return [index[i : i + batch_size] for i in range(0, len(index), batch_size)]


def batch_to_tensor(patches: np.ndarray, device: torch.device) -> torch.Tensor:
    """One batch of float16 (or any float) patches → float32 tensor on ``device``."""
    return torch.from_numpy(np.ascontiguousarray(patches)).to(device=device, dtype=torch.float32)


def channel_statistics(patches: np.ndarray, index: np.ndarray | None = None,
                       chunk: int = 4096) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel mean and standard deviation of ``patches[index]`` (N, 6, H, W), each (6,).

    Computed in float64 over chunks (no float32 copy of the whole set) on the input
    as :class:`DGTNet` sees it (H̄ relative to each patch's mean, ``centre_heights``);
    NaN cells are skipped. A channel with (near) zero spread gets std 1.
    """
    index = np.arange(len(patches)) if index is None else np.asarray(index)
    if len(index) == 0:
        raise ValueError("cannot compute normalisation statistics of zero patches")
    total = np.zeros(N_CHANNELS)
    total_sq = np.zeros(N_CHANNELS)
    count = np.zeros(N_CHANNELS)
    for idx in _index_batches(index, chunk):
        x = centre_heights(patches[idx].astype(np.float64))  # (b, 6, H, W), as DGTNet sees it
        finite = np.isfinite(x)
        x = np.where(finite, x, 0.0)
        total += x.sum(axis=(0, 2, 3))
        total_sq += (x * x).sum(axis=(0, 2, 3))
        count += finite.sum(axis=(0, 2, 3))
    count = np.maximum(count, 1)
    mean = total / count
    std = np.sqrt(np.maximum(total_sq / count - mean**2, 0.0))
    std = np.where(std > 1e-6, std, 1.0)
    return mean.astype(np.float32), std.astype(np.float32)


@torch.no_grad()
def _predict_index(model: DGTNet, patches: np.ndarray, index: np.ndarray, batch_size: int,
                   device: torch.device) -> np.ndarray:
    was_training = model.training
    model.eval()
    out = np.empty((len(index), len(model.vehicles)), dtype=np.float32)
    for start in range(0, len(index), batch_size):
        idx = index[start : start + batch_size]
        out[start : start + len(idx)] = model(batch_to_tensor(patches[idx], device)).cpu().numpy()
    model.train(was_training)
    return out


def predict(model: DGTNet, patches: np.ndarray, batch_size: int = 1024) -> np.ndarray:
    """Locomotion of every head for raw patches (N, 6, 22, 7) → (N, n_heads) float32 in [0, 1].

    Runs in eval mode on the model's device, ``batch_size`` patches at a time,
    converting each batch (e.g. float16) to float32 on the fly.
    """
    patches = np.asarray(patches)
    if patches.ndim != 4 or patches.shape[1] != N_CHANNELS:
        raise ValueError(f"expected patches (N, {N_CHANNELS}, 22, 7), got {patches.shape}")
    return _predict_index(model, patches, np.arange(len(patches)), batch_size,
                          next(model.parameters()).device)


def window_predictor(model: DGTNet, batch_size: int = 1024
                     ) -> Callable[[np.ndarray], np.ndarray]:
    """:func:`predict` for a costmap's windows, on a copy of ``model`` whose convolution
    weights are stored channels-last (N, H, W, C): CPU convolutions of 22 × 7 patches run
    2–3× faster in that layout (``benchmarks/bench_costmap.py``) and give the same function
    up to float rounding (|ΔL| ≤ 1e-6). ``model`` itself keeps its layout, so training and
    its validation are untouched."""
    fast = copy.deepcopy(model).to(memory_format=torch.channels_last)
    return lambda patches: predict(fast, patches, batch_size)


def _head_columns(heads: Sequence[str], vehicle: np.ndarray) -> np.ndarray:
    """Output column of each sample's vehicle among ``heads`` (-1 where there is none)."""
    lookup = np.full(len(VEHICLES), -1, dtype=np.int64)
    for j, name in enumerate(heads):
        lookup[VEHICLES.index(name)] = j
    return lookup[vehicle.astype(np.int64)]


COLLAPSE_RATIO = 0.1
"""A head whose test predictions spread less than this fraction of the labels' spread
(std of L̂ < 0.1 × std of L) has collapsed to a (near) constant."""


def regression_metrics(pred: np.ndarray, true: np.ndarray) -> dict[str, float]:
    """``n``, ``mse``, ``mae``, Spearman rank correlation ``spearman`` and the spreads
    (standard deviations) ``pred_std`` and ``label_std`` of two (n,) arrays.

    ``spearman`` is NaN when it is undefined (fewer than 2 samples or a constant array).
    """
    pred = np.asarray(pred, dtype=np.float64)
    true = np.asarray(true, dtype=np.float64)
    err = pred - true
    rho = float("nan")
    if len(true) >= 2 and np.ptp(true) > 0 and np.ptp(pred) > 0:
        from scipy import stats  # ~0.3 s to import: not on every `dgt` command's path

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rho = float(stats.spearmanr(pred, true).statistic)
    return {"n": int(len(true)), "mse": float(np.mean(err**2)) if len(err) else float("nan"),
            "mae": float(np.mean(np.abs(err))) if len(err) else float("nan"), "spearman": rho,
            "pred_std": float(np.std(pred)) if len(pred) else float("nan"),
            "label_std": float(np.std(true)) if len(true) else float("nan")}


def collapsed_heads(metrics: dict[str, dict[str, float]]) -> list[str]:
    """The vehicles whose head predicts (nearly) the same L̂ for every test patch:
    std(L̂) < :data:`COLLAPSE_RATIO` × std(L).

    That happens when a sigmoid head saturates early in training (docs/training.md).
    ``metrics`` as in :attr:`TrainResult.metrics`; checkpoints without ``pred_std``
    (made before it was recorded) never count.
    """
    return [v for v, m in metrics.items()
            if m.get("pred_std", math.inf) < COLLAPSE_RATIO * m.get("label_std", 0.0)]


def evaluate(model: DGTNet, part: PatchDataset, batch_size: int = 1024,
             codes: Sequence[int] | None = None) -> dict[str, dict[str, float]]:
    """Per-vehicle metrics of the model's own head on ``part`` (e.g. ``dataset.part("test")``).

    Returns ``{vehicle: {"n", "mse", "mae", "spearman"}}`` for every vehicle that
    has a head in ``model`` and samples in ``part``; each prediction is that
    vehicle's head on that vehicle's patches. ``codes``: each head's value in
    ``part.vehicle`` (default its index into ``config.VEHICLES``).
    """
    out: dict[str, dict[str, float]] = {}
    codes = _codes(model.vehicles, codes)
    for name, code in zip(model.vehicles, codes, strict=True):
        index = np.flatnonzero(part.vehicle == code)
        if len(index) == 0:
            continue
        device = next(model.parameters()).device
        pred = _predict_index(model, part.patches, index, batch_size, device)
        out[name] = regression_metrics(pred[:, model.head_index(name)], part.labels[index])
    return out


def _codes(vehicles: Sequence[str], codes: Sequence[int] | None) -> list[int]:
    """Each vehicle's value in ``PatchDataset.vehicle``: ``codes`` when given (a
    :attr:`TrainingSet.codes`), else its index into ``config.VEHICLES``."""
    return [VEHICLES.index(v) for v in vehicles] if codes is None else list(codes)


def head_prior(dataset: PatchDataset, index: np.ndarray,
               vehicles: tuple[str, ...] | list[str],
               codes: Sequence[int] | None = None) -> list[float]:
    """Mean label of each vehicle's samples among ``index``, in ``vehicles`` order.

    What :meth:`DGTNet.init_heads` starts each head at (``TrainConfig.head_init="prior"``);
    ``index`` is the training split. A vehicle without samples there (its head gets
    no gradient) gets the mean of all of ``index``. ``codes``: each vehicle's value in
    ``dataset.vehicle`` (default its index into ``config.VEHICLES``).
    """
    labels = dataset.labels[index].astype(np.float64)
    vehicle = dataset.vehicle[index]
    overall = float(labels.mean()) if len(labels) else 0.5
    return [float(labels[vehicle == c].mean()) if np.any(vehicle == c) else overall
            for c in _codes(vehicles, codes)]




def stopped_early(cfg: TrainConfig, epoch: int, best_epoch: int) -> bool:
    """Whether early stopping ends training after ``epoch``: ``cfg.patience`` epochs
    without a better validation loss than ``best_epoch``'s (``selection="best_val"``)."""
    return (cfg.selection == "best_val" and cfg.patience is not None
            and epoch - best_epoch >= cfg.patience)


def _vehicle_tuple(vehicles: tuple[str, ...] | list[str] | str | None) -> tuple[str, ...]:
    if vehicles is None:
        return VEHICLES
    vehicles = (vehicles,) if isinstance(vehicles, str) else tuple(vehicles)
    unknown = [v for v in vehicles if v not in VEHICLES]
    if not vehicles or unknown:
        raise ValueError(f"unknown vehicle(s) {unknown or vehicles}; valid: {VEHICLES}")
    return vehicles


class MultiHeadNet(Protocol):
    """What :func:`train_epoch`, :func:`fit` and :func:`~dgt_lib.learning.run.train_network`
    train: a ``torch.nn.Module`` mapping a batch of patches (B, C, H, W) float32 to
    L̂ (B, V) in [0, 1], column j for vehicle ``vehicles[j]``, with its input normalisation
    set; ``init_heads`` starts each head at a mean label (``TrainConfig.head_init="prior"``).
    :class:`DGTNet` is one."""

    vehicles: tuple[str, ...]

    def __call__(self, x: torch.Tensor) -> torch.Tensor: ...

    def init_heads(self, mean_labels: Sequence[float], weight_scale: float = 0.1) -> None: ...


@dataclass
class TrainingSet:
    """The samples one training reads: ``dataset`` with the training and validation
    indices of ``vehicles``' samples and each sample's output column (``heads``, -1 for
    other vehicles)."""

    dataset: PatchDataset
    vehicles: tuple[str, ...]
    chosen: np.ndarray  # (N,) bool: a sample of one of ``vehicles``
    train_index: np.ndarray
    val_index: np.ndarray
    heads: np.ndarray  # (N,) int64
    # each vehicle's value in dataset.vehicle; None: its index into config.VEHICLES
    codes: tuple[int, ...] | None = None

    @classmethod
    def select(cls, dataset: PatchDataset, vehicles: tuple[str, ...] | list[str] | str | None,
               cfg: TrainConfig) -> TrainingSet:
        """``vehicles``' samples of ``dataset`` (None: all four), checked: ≥ 2 training and
        ≥ 1 validation samples, labels in [0, 1], ``cfg.epochs`` ≥ 1, ``cfg.batch_size`` ≥ 2."""
        vehicles = _vehicle_tuple(vehicles)
        if cfg.epochs < 1 or cfg.batch_size < 2:
            raise ValueError(f"need epochs ≥ 1 and batch_size ≥ 2, got {cfg.epochs}, "
                             f"{cfg.batch_size}")
        chosen = np.isin(dataset.vehicle, [VEHICLES.index(v) for v in vehicles])
        train_idx = np.flatnonzero(chosen & (dataset.split == TRAIN))
        val_idx = np.flatnonzero(chosen & (dataset.split == VAL))
        if len(train_idx) < 2 or len(val_idx) == 0:
            raise ValueError(f"{vehicles}: need ≥ 2 training and ≥ 1 validation samples, "
                             f"got {len(train_idx)} and {len(val_idx)}")
        used = dataset.labels[np.concatenate([train_idx, val_idx])]
        if not np.all((used >= 0) & (used <= 1)):  # also catches NaN
            raise ValueError("labels must be locomotion values in [0, 1]; found "
                             f"{np.sum(~((used >= 0) & (used <= 1)))} outside (or NaN)")
        return cls(dataset, vehicles, chosen, train_idx, val_idx,
                   _head_columns(vehicles, dataset.vehicle))

    def targets(self, idx: np.ndarray, device: torch.device
                ) -> tuple[torch.Tensor, torch.Tensor]:
        """Labels (B,) float32 and output columns (B,) of samples ``idx``."""
        labels = torch.from_numpy(self.dataset.labels[idx].astype(np.float32)).to(device)
        return labels, torch.from_numpy(self.heads[idx]).to(device)

    def batches(self, order: np.ndarray, batch_size: int) -> list[np.ndarray]:
        """``order`` in minibatches; a last batch of one is dropped (BatchNorm needs ≥ 2)."""
        return [b for b in _index_batches(order, batch_size) if len(b) >= 2]

    def validation_loss(self, model: MultiHeadNet, device: torch.device) -> float:
        """Mean :func:`masked_loss` over the validation samples (eval mode, no gradient)."""
        index = self.val_index
        pred = _predict_index(model, self.dataset.patches, index, 1024, device)
        return masked_loss(torch.from_numpy(pred).double(),
                           torch.from_numpy(self.dataset.labels[index]).double(),
                           torch.from_numpy(self.heads[index])).item()


def train_epoch(model: MultiHeadNet, optimizer: torch.optim.Optimizer, data: TrainingSet,
                cfg: TrainConfig, rng: np.random.Generator, device: torch.device, *,
                step: int = 0, total_steps: int = 1,
                on_step: Callable[[int, float, float], None] | None = None,
                loss_fn: Callable[..., torch.Tensor] = masked_loss) -> float:
    """One epoch: the training samples in a random order, in minibatches; per batch the
    masked loss ``loss_fn(pred, labels, head)`` (:func:`masked_loss`), its
    gradient, and one Adam step at the rate :func:`learning_rate_at` gives optimiser step
    ``step`` of ``total_steps``. With ``cfg.mirror_augment`` each patch is mirrored
    left ↔ right with probability ½ (a vehicle's locomotion does not care).
    ``on_step(i, loss, mean_so_far)`` after each batch i. Returns the epoch's mean loss.
    """
    model.train()
    order = rng.permutation(data.train_index)
    total, seen = 0.0, 0
    for i, idx in enumerate(data.batches(order, cfg.batch_size)):
        x = batch_to_tensor(data.dataset.patches[idx], device)  # (B, C, H, W) float32
        if cfg.mirror_augment:
            flip = torch.from_numpy(rng.random(len(idx)) < 0.5).to(device)
            x = torch.where(flip[:, None, None, None], x.flip(-1), x)
        pred, (labels, heads) = model(x), data.targets(idx, device)
        loss = loss_fn(pred, labels, heads)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        for group in optimizer.param_groups:
            group["lr"] = learning_rate_at(cfg, step, total_steps)
        optimizer.step()
        step += 1
        value = loss.item()
        total += value * len(idx)
        seen += len(idx)
        if on_step is not None:
            on_step(i, value, total / seen)
    return total / seen


@dataclass
class FitState:
    """A training after its epoch ``epoch`` (0: none yet): the history, the best epoch so
    far with its validation loss and weights (CPU), and the optimiser steps taken."""

    epoch: int = 0
    step_count: int = 0
    history: list[dict[str, float]] = field(default_factory=list)
    best_epoch: int = 0
    best_val: float = math.inf
    best_state: dict[str, torch.Tensor] | None = None


class FitHooks:
    """What :func:`fit` tells the run around it (:mod:`dgt_lib.learning.run`): progress,
    checkpoints, snapshots. These do nothing."""

    def epoch_start(self, epoch: int, n_batches: int) -> None:
        """Epoch ``epoch`` (1-based) starts, with ``n_batches`` minibatches."""

    def step(self, epoch: int, i: int, loss: float, mean: float) -> None:
        """Batch ``i`` of ``epoch`` is done: its loss, the epoch's mean so far."""

    def epoch_end(self, state: FitState, improved: bool) -> None:
        """Epoch ``state.epoch`` is done; ``improved``: its weights are the best so far."""


def fit(model: MultiHeadNet, optimizer: torch.optim.Optimizer, data: TrainingSet,
        cfg: TrainConfig, rng: np.random.Generator, device: torch.device,
        state: FitState | None = None, hooks: FitHooks | None = None) -> FitState:
    """Train for ``cfg.epochs`` epochs (from after ``state.epoch``) with :func:`train_epoch`;
    after each, the validation loss picks the weights to keep (``cfg.selection``:
    ``"best_val"`` the lowest, ``"last"`` the last) and early stopping may end it
    (``cfg.patience``). Returns ``state`` (updated in place: an interrupt leaves it at the
    last finished epoch)."""
    state = FitState() if state is None else state
    hooks = FitHooks() if hooks is None else hooks
    n_batches = len(data.batches(data.train_index, cfg.batch_size))
    if state.epoch and stopped_early(cfg, state.epoch, state.best_epoch):
        return state
    for epoch in range(state.epoch + 1, cfg.epochs + 1):
        t0 = time.perf_counter()
        hooks.epoch_start(epoch, n_batches)
        train_loss = train_epoch(model, optimizer, data, cfg, rng, device,
                                 step=state.step_count, total_steps=cfg.epochs * n_batches,
                                 on_step=lambda i, loss, mean, e=epoch: hooks.step(e, i, loss,
                                                                                   mean))
        val = data.validation_loss(model, device)
        state.step_count += n_batches
        state.epoch = epoch
        state.history.append({"epoch": epoch, "train_loss": train_loss, "val_loss": val,
                              "seconds": time.perf_counter() - t0})
        improved = val < state.best_val or cfg.selection == "last"
        if improved:
            state.best_val, state.best_epoch = val, epoch
            state.best_state = {k: v.detach().to("cpu", copy=True)
                                for k, v in model.state_dict().items()}
        hooks.epoch_end(state, improved)
        if stopped_early(cfg, epoch, state.best_epoch):
            break
    return state
