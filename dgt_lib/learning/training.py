"""Multi-task training of :class:`~dgt_lib.learning.model.DGTNet`, its single-task
variant, and metrics.

Paper: Multi-Task Learning and Baselines (DGT-Map(ST)). The multi-task
model is trained on every vehicle's patches at once with the masked loss
(:func:`masked_loss`): a patch of vehicle v trains the shared backbone and head v
only. The single-task variant is the same architecture with one head, trained on
one vehicle's data. Plain shuffled minibatches over all training samples (the
dataset's vehicle imbalance is kept, as in the paper). Ours, beyond the paper: each head
starts at its vehicle's prior (``TrainConfig.head_init``), and the loss can weight rare
labels up (``TrainConfig.label_weighting``, off by default).

Typical use::

    result = train_model(dataset, profile.train, seed=0)              # multi-task
    single = train_model(dataset, profile.train, vehicles=("vw_van",))
    # cached per profile and seed: dgt_lib.stages.train.ensure_model(profile, dataset, kind)
    L_hat = predict(result.model, patches)                            # (N, n_heads)

Training keeps the weights of the epoch with the lowest validation loss
(``TrainConfig.selection="best_val"``) or of the last epoch (``"last"``, with the cosine
learning-rate schedule ``TrainConfig.lr_schedule="cosine"``); Ctrl-C
(KeyboardInterrupt) stops it cleanly and returns (and, with ``checkpoint_path``,
has saved) that model — or, with ``keep_best_on_interrupt=False`` (the cached
pipeline), lets the interrupt through so that nothing half-trained is kept. With
``snapshot_path`` the training is saved after an epoch (:mod:`dgt_lib.learning.resume`) and
the next call resumes after it: an interrupt or a crash costs at most ~1 min and an epoch.
"""

from __future__ import annotations

import copy
import math
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from dgt_lib.core.config import VEHICLES, TrainConfig
from dgt_lib.learning.checkpoints import TrainResult, save_checkpoint
from dgt_lib.learning.model import N_CHANNELS, DGTNet, centre_heights
from dgt_lib.learning.resume import TrainingState, load_training_state, training_identity
from dgt_lib.perception.dataset import TEST, TRAIN, VAL, PatchDataset


def masked_loss(pred: torch.Tensor, labels: torch.Tensor, head: torch.Tensor,
                weight: torch.Tensor | None = None) -> torch.Tensor:
    """The multi-task loss of a batch (paper: Multi-Task Learning).

        𝓛(P, v) = ‖L̂_v(P) − L_v(t_P)‖²

    Only the head of the vehicle that collected patch P contributes; the other
    heads' outputs are not used, so they get exactly zero gradient from P.
    pred: (B, n_heads) predictions; labels: (B,) L_v(t_P); head: (B,) int64 column
    of each sample's vehicle; weight: optional (B,) sample weights w_P
    (:func:`label_weights`). Returns the mean over the batch, Σ w_P 𝓛(P) / Σ w_P with
    weights (a scalar).
    """
    chosen = pred.gather(1, head[:, None]).squeeze(1)  # (B,) L̂_v(P)
    if weight is None:
        return torch.mean((chosen - labels) ** 2)
    return torch.sum(weight * (chosen - labels) ** 2) / torch.sum(weight)


def label_weights(labels: np.ndarray, vehicle: np.ndarray, train_index: np.ndarray,
                  n_bins: int = 5, max_weight: float = 10.0) -> np.ndarray:
    """Inverse-frequency sample weights (N,) float32 for imbalanced labels (ours).

    Per vehicle v, its training labels are binned in ``n_bins`` equal bins of [0, 1];
    a sample of v whose label falls in bin b gets

        w = min(n_v / (B_v · n_{v,b}), max_weight),   then scaled to mean 1 over v's
                                                       training samples,

    with n_v the vehicle's training samples, n_{v,b} those in bin b and B_v its
    non-empty bins: every occupied bin weighs about the same in the loss. A jeep whose
    labels are 97 % ≈ 1 then learns from its few stalls instead of averaging them
    away. Samples of bins with no training sample (validation, test) get the cap.
    """
    labels = np.asarray(labels, np.float64)
    bins = np.clip((labels * n_bins).astype(np.int64), 0, n_bins - 1)
    weights = np.ones(len(labels), np.float64)
    train = np.zeros(len(labels), bool)
    train[train_index] = True
    for v in np.unique(vehicle):
        own = vehicle == v
        counts = np.bincount(bins[own & train], minlength=n_bins).astype(np.float64)
        if counts.sum() == 0:
            continue
        per_bin = np.where(counts > 0, counts.sum() / (np.count_nonzero(counts)
                                                        * np.maximum(counts, 1)), max_weight)
        w = np.minimum(per_bin[bins], max_weight)
        weights[own] = w[own] / w[own & train].mean()
    return weights.astype(np.float32)


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
    weights settle instead of jumping between minibatch noise (at a constant 1e-3 the demo
    validation loss moved by up to 10× from one epoch to the next)."""
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


def _model_device(model: torch.nn.Module) -> torch.device:
    return next(model.parameters()).device


def predict(model: DGTNet, patches: np.ndarray, batch_size: int = 1024) -> np.ndarray:
    """Locomotion of every head for raw patches (N, 6, 22, 7) → (N, n_heads) float32 in [0, 1].

    Runs in eval mode on the model's device, ``batch_size`` patches at a time,
    converting each batch (e.g. float16) to float32 on the fly.
    """
    patches = np.asarray(patches)
    if patches.ndim != 4 or patches.shape[1] != N_CHANNELS:
        raise ValueError(f"expected patches (N, {N_CHANNELS}, 22, 7), got {patches.shape}")
    return _predict_index(model, patches, np.arange(len(patches)), batch_size,
                          _model_device(model))


def _head_columns(model: DGTNet, vehicle: np.ndarray) -> np.ndarray:
    """Model output column of each sample's vehicle (-1 where the model has no head)."""
    lookup = np.full(len(VEHICLES), -1, dtype=np.int64)
    for j, name in enumerate(model.vehicles):
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

    That happens when a sigmoid head saturates early in training (e.g. on labels that
    are almost all ≈ 1): the model then carries next to no terrain information.
    ``metrics`` as in :attr:`TrainResult.metrics`; checkpoints without ``pred_std``
    (made before it was recorded) never count.
    """
    return [v for v, m in metrics.items()
            if m.get("pred_std", math.inf) < COLLAPSE_RATIO * m.get("label_std", 0.0)]


def evaluate(model: DGTNet, part: PatchDataset,
             batch_size: int = 1024) -> dict[str, dict[str, float]]:
    """Per-vehicle metrics of the model's own head on ``part`` (e.g. ``dataset.part("test")``).

    Returns ``{vehicle: {"n", "mse", "mae", "spearman"}}`` for every vehicle that
    has a head in ``model`` and samples in ``part``; each prediction is that
    vehicle's head on that vehicle's patches.
    """
    out: dict[str, dict[str, float]] = {}
    for name in model.vehicles:
        index = np.flatnonzero(part.vehicle == VEHICLES.index(name))
        if len(index) == 0:
            continue
        pred = _predict_index(model, part.patches, index, batch_size, _model_device(model))
        out[name] = regression_metrics(pred[:, model.head_index(name)], part.labels[index])
    return out


def _validation_loss(model: DGTNet, dataset: PatchDataset, index: np.ndarray,
                     columns: np.ndarray, batch_size: int, device: torch.device,
                     weights: np.ndarray | None = None) -> float:
    """Mean :func:`masked_loss` over the samples ``index`` (eval mode, no gradient),
    weighted like training when ``weights`` (N,) are given."""
    pred = _predict_index(model, dataset.patches, index, batch_size, device)
    w = None if weights is None else torch.from_numpy(weights[index]).double()
    return masked_loss(torch.from_numpy(pred).double(),
                       torch.from_numpy(dataset.labels[index]).double(),
                       torch.from_numpy(columns[index]), w).item()


def head_prior(dataset: PatchDataset, index: np.ndarray,
               vehicles: tuple[str, ...] | list[str]) -> list[float]:
    """Mean label of each vehicle's samples among ``index``, in ``vehicles`` order.

    What :meth:`DGTNet.init_heads` starts each head at (``TrainConfig.head_init="prior"``);
    ``index`` is the training split. A vehicle without samples there (its head gets
    no gradient) gets the mean of all of ``index``.
    """
    labels = dataset.labels[index].astype(np.float64)
    vehicle = dataset.vehicle[index]
    overall = float(labels.mean()) if len(labels) else 0.5
    return [float(labels[vehicle == VEHICLES.index(v)].mean())
            if np.any(vehicle == VEHICLES.index(v)) else overall for v in vehicles]


def _stopped_early(cfg: TrainConfig, epoch: int, best_epoch: int) -> bool:
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


def train_model(
    dataset: PatchDataset,
    cfg: TrainConfig,
    *,
    vehicles: tuple[str, ...] | list[str] | str | None = None,
    seed: int = 0,
    device: str | torch.device | None = None,
    progress: bool = True,
    rgb_weights: str | Path | None = None,
    checkpoint_path: str | Path | None = None,
    on_batch_end: Callable[[int, int, float], None] | None = None,
    keep_best_on_interrupt: bool = True,
    model: torch.nn.Module | None = None,
    snapshot_path: str | Path | None = None,
    snapshot_key: Any = None,
    snapshot_every_s: float = 60.0,
) -> TrainResult:
    """Train a DGTNet with Adam and the masked loss; keep the epoch ``cfg.selection`` picks.

    Args:
        dataset: all patches with their ``split``; only TRAIN updates weights, VAL
            picks the best epoch, TEST gives ``TrainResult.metrics``.
        cfg: epochs, batch size, learning rate, width … (``profile.train``);
            ``head_init="prior"`` starts each head at logit(its vehicle's mean training
            label) with its weights × 0.1 (:meth:`DGTNet.init_heads`, :func:`head_prior`),
            ``"default"`` keeps PyTorch's init (can saturate on skewed labels).
        vehicles: None = multi-task on every vehicle (one head each); a tuple of
            names (e.g. ``("vw_van",)``) trains only on those vehicles' samples
            with one head each (the single-task variant).
        seed: seeds weight initialisation and batch order; same seed, same result
            on the CPU with the same thread count (on a GPU, cuDNN's kernels vary
            slightly from run to run).
        device: default: a CUDA GPU when present, else the CPU.
        progress: tqdm bars with the live loss.
        rgb_weights: torchvision ImageNet ResNet-18 file for the RGB branch (width 64).
        checkpoint_path: if given, the best model so far is saved there (atomically,
            :func:`save_checkpoint`) each time the validation loss improves.
        on_batch_end: called as ``on_batch_end(epoch, step, loss)`` after every step.
        keep_best_on_interrupt: what Ctrl-C (KeyboardInterrupt) does. True: training
            ends after the last finished epoch and the result holds the best weights so
            far with ``interrupted=True`` (an interrupt before the first epoch finishes
            has nothing to keep and is re-raised). False: the interrupt is re-raised at
            once (the caller stops; nothing is evaluated or saved).
        model: a network to train in place of a new DGTNet (e.g.
            :class:`~dgt_lib.beyond.pooled.PooledNet`): it must take batches of
            ``dataset.patches``, have one head per name of ``vehicles`` and its input
            normalisation already set; ``width``, ``fc_hidden`` and ``rgb_weights`` are then
            not used.
        snapshot_path: if given, the training's state after a finished epoch is saved
            there (``.pt``, atomically; :class:`~dgt_lib.learning.resume.TrainingState`)
            whenever ``snapshot_every_s`` have passed since the last one, and a snapshot
            found there of this same training (settings, vehicles, seed,
            network, data and ``snapshot_key``) is resumed: the epochs after it run, and the
            result equals that of a training never stopped (on the CPU, bit for bit; on a GPU
            two trainings never stopped differ already). A snapshot of another training
            is overwritten. The file stays when training ends (the caller deletes it once
            the result is stored: :func:`~dgt_lib.stages.train.ensure_model` does).
        snapshot_key: anything else that makes this training what it is for the snapshot
            (e.g. the model cache's configuration); JSON-able.
        snapshot_every_s: the least wall time between two snapshots [s] (0: after every
            epoch). A width-64 snapshot is 270–360 MB and takes 0.4–1.5 s to write; the default
            keeps that within training's run-to-run spread (``benchmarks/bench_resume.py``)
            and an interrupt costs at most a minute plus the epoch in progress.
    """
    vehicles = _vehicle_tuple(vehicles)
    if cfg.epochs < 1 or cfg.batch_size < 2:
        raise ValueError(f"need epochs ≥ 1 and batch_size ≥ 2, got {cfg.epochs}, {cfg.batch_size}")
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
    device = resolve_device(device)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    if model is not None and checkpoint_path is not None:
        raise ValueError("checkpoint_path saves DGTNet checkpoints; save another model yourself")
    if model is None:
        model = DGTNet(vehicles, width=cfg.width, fc_hidden=cfg.fc_hidden,
                       rgb_weights=rgb_weights)
        model.set_normalization(*channel_statistics(dataset.patches, train_idx))
    elif tuple(model.vehicles) != vehicles:
        raise ValueError(f"the model's heads {model.vehicles} are not the vehicles {vehicles}")
    if cfg.head_init == "prior":
        model.init_heads(head_prior(dataset, train_idx, vehicles))
    live_taps = cfg.conv_taps == "live" and isinstance(model, DGTNet)
    if live_taps:
        model.use_live_taps()
    model.to(device)
    columns = _head_columns(model, dataset.vehicle)  # (N,) model column per sample
    optimizer = torch.optim.Adam(model.parameters(), lr=cfg.learning_rate,
                                 weight_decay=cfg.weight_decay)
    labels = torch.from_numpy(dataset.labels.astype(np.float32))
    heads = torch.from_numpy(columns)
    weights = None
    if cfg.label_weighting == "inverse_frequency":
        weights = label_weights(dataset.labels, dataset.vehicle, train_idx, cfg.label_bins,
                                cfg.max_label_weight)
    sample_w = None if weights is None else torch.from_numpy(weights)

    history: list[dict[str, float]] = []
    best_state: dict[str, torch.Tensor] | None = None
    best_epoch, best_val, interrupted = 0, float("inf"), False
    name = "multi-task" if len(vehicles) > 1 else f"single-task {vehicles[0]}"
    steps_per_epoch = sum(len(b) >= 2 for b in _index_batches(train_idx, cfg.batch_size))
    total_steps, step_count, first_epoch = cfg.epochs * steps_per_epoch, 0, 1
    identity, saved_epoch = None, 0  # saved_epoch: the last epoch in the snapshot file
    last_snapshot = time.perf_counter()
    if snapshot_path is not None:
        identity = training_identity(cfg, vehicles, seed, model, dataset.patches,
                                     dataset.labels, train_idx, val_idx, snapshot_key)
        state, why = load_training_state(snapshot_path, identity)
        if state is not None:
            best_state = state.restore(model, optimizer, rng)
            history, step_count = state.history, state.step_count
            best_epoch, best_val = state.best_epoch, state.best_val
            saved_epoch = state.epoch
            first_epoch = (cfg.epochs + 1 if _stopped_early(cfg, saved_epoch, best_epoch)
                           else saved_epoch + 1)
            tqdm.write(f"[dgt] {name}: resuming after epoch {state.epoch} ({snapshot_path})")
        elif why != "missing":
            tqdm.write(f"[dgt] {name}: not resuming the snapshot {snapshot_path}, {why}; "
                       "training from the start")
    epochs_bar = tqdm(range(first_epoch, cfg.epochs + 1), desc=f"train {name}", unit="epoch",
                      initial=first_epoch - 1, total=cfg.epochs, disable=not progress)
    batch_bar = None
    try:
        for epoch in epochs_bar:
            t0 = time.perf_counter()
            model.train()
            order = rng.permutation(train_idx)
            batches = [b for b in _index_batches(order, cfg.batch_size) if len(b) >= 2]
            total, seen = 0.0, 0  # BatchNorm needs ≥ 2 samples: a last batch of 1 is skipped
            batch_bar = tqdm(batches, desc=f"epoch {epoch}", unit="batch", leave=False,
                             disable=not progress)
            for step, idx in enumerate(batch_bar):
                x = batch_to_tensor(dataset.patches[idx], device)  # (B, 6, 22, 7) float32
                if cfg.mirror_augment:  # left ↔ right: a vehicle's locomotion does not care
                    flip = torch.from_numpy(rng.random(len(idx)) < 0.5).to(device)
                    x = torch.where(flip[:, None, None, None], x.flip(-1), x)
                loss = masked_loss(model(x), labels[idx].to(device), heads[idx].to(device),
                                   None if sample_w is None else sample_w[idx].to(device))
                optimizer.zero_grad(set_to_none=True)
                loss.backward()
                for group in optimizer.param_groups:
                    group["lr"] = learning_rate_at(cfg, step_count, total_steps)
                optimizer.step()
                step_count += 1
                value = loss.item()
                total += value * len(idx)
                seen += len(idx)
                batch_bar.set_postfix(loss=f"{total / seen:.4f}")
                if on_batch_end is not None:
                    on_batch_end(epoch, step, value)
            batch_bar.close()
            val = _validation_loss(model, dataset, val_idx, columns, 1024, device, weights)
            history.append({"epoch": epoch, "train_loss": total / seen, "val_loss": val,
                            "seconds": time.perf_counter() - t0})
            if val < best_val or cfg.selection == "last":
                best_val, best_epoch = val, epoch
                best_state = {k: v.detach().to("cpu", copy=True)
                              for k, v in model.state_dict().items()}
                if checkpoint_path is not None:  # the model holds the best weights right now
                    save_checkpoint(checkpoint_path, TrainResult(
                        model, copy.deepcopy(history), best_epoch, {}, False, cfg, seed))
            if (snapshot_path is not None
                    and time.perf_counter() - last_snapshot >= snapshot_every_s):
                TrainingState.capture(identity, epoch, step_count, model, optimizer, rng,
                                      history, best_epoch, best_val, best_state
                                      ).save(snapshot_path)
                saved_epoch, last_snapshot = epoch, time.perf_counter()
            epochs_bar.set_postfix(train=f"{total / seen:.4f}", val=f"{val:.4f}",
                                   best=best_epoch)
            if _stopped_early(cfg, epoch, best_epoch):
                break
    except KeyboardInterrupt:
        if saved_epoch:
            epochs = "epoch 1 is" if saved_epoch == 1 else f"epochs 1–{saved_epoch} are"
            tqdm.write(f"[dgt] {name}: {epochs} saved in {snapshot_path}; "
                       f"the next run resumes after epoch {saved_epoch}")
        if best_state is None or not keep_best_on_interrupt:
            raise
        interrupted = True
        tqdm.write(f"[dgt] training interrupted: keeping epoch {best_epoch} "
                   f"(val loss {best_val:.4f})")
    finally:
        if batch_bar is not None:
            batch_bar.close()
        epochs_bar.close()
        if live_taps:
            model.use_live_taps(False)  # the trained network evaluates with its full kernels
    if best_state is None:
        raise RuntimeError(f"training {name} diverged: validation loss "
                           f"{[h['val_loss'] for h in history]}; try a lower learning rate")
    model.load_state_dict(best_state)
    model.eval()
    metrics = evaluate(model, dataset.subset(chosen & (dataset.split == TEST)))
    for v in collapsed_heads(metrics):
        m = metrics[v]
        warnings.warn(f"{name}: the {v} head predicts a near-constant L̂ on the test set "
                      f"(std {m['pred_std']:.1e} against the labels' {m['label_std']:.2f}): "
                      "it learned next to nothing (too few epochs, or a saturated sigmoid)",
                      stacklevel=2)
    result = TrainResult(model, history, best_epoch, metrics, interrupted, cfg, seed)
    if checkpoint_path is not None:
        save_checkpoint(checkpoint_path, result)
    return result
