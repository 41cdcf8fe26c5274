"""Multi-task training of :class:`~dgt_lib.model.DGTNet`, its single-task variant, and metrics.

Paper: Multi-Task Learning and Baselines (DGT-Map(Single-Task)). The multi-task
model is trained on every vehicle's patches at once with the masked loss
(:func:`masked_loss`): a patch of vehicle v trains the shared backbone and head v
only. The single-task variant is the same architecture with one head, trained on
one vehicle's data. Plain shuffled minibatches over all training samples (the
dataset's vehicle imbalance is kept, as in the paper).

Typical use::

    result = train_model(dataset, profile.train, seed=0)              # multi-task
    single = train_model(dataset, profile.train, vehicles=("vw_van",))
    result = ensure_model(profile, dataset, kind="single:vw_van")     # cached
    L_hat = predict(result.model, patches)                            # (N, n_heads)

Training keeps the weights of the epoch with the lowest validation loss; Ctrl-C
(KeyboardInterrupt) stops it cleanly and returns (and, with ``checkpoint_path``,
has saved) that best model.
"""

from __future__ import annotations

import copy
import math
import os
import time
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from scipy import stats
from tqdm.auto import tqdm

from . import artifacts
from .config import VEHICLES, Profile, TrainConfig
from .dataset import TEST, TRAIN, VAL, PatchDataset, split_by_trajectory
from .model import N_CHANNELS, ArchitectureMismatchError, DGTNet, centre_heights
from .pipeline import StageOutput

CHECKPOINT_FORMAT = "dgt-kit/DGTNet"
CHECKPOINT_VERSION = 2
MODEL_KINDS: tuple[str, ...] = ("multitask",) + tuple(f"single:{v}" for v in VEHICLES)
"""The models of ``ensure_model``: multi-task, and one single-task model per vehicle."""
RGB_WEIGHTS_ENV_VAR = "DGT_RESNET18_WEIGHTS"
RGB_WEIGHTS_FILE = "resnet18-f37072fd.pth"
"""torchvision's ImageNet ResNet-18 file name; looked for under ``data/`` by ``ensure_model``."""


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
                     columns: np.ndarray, batch_size: int, device: torch.device) -> float:
    """Mean :func:`masked_loss` over the samples ``index`` (eval mode, no gradient)."""
    pred = _predict_index(model, dataset.patches, index, batch_size, device)
    return masked_loss(torch.from_numpy(pred).double(),
                       torch.from_numpy(dataset.labels[index]).double(),
                       torch.from_numpy(columns[index])).item()


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
) -> TrainResult:
    """Train a DGTNet with Adam and the masked loss; keep the best validation epoch.

    Args:
        dataset: all patches with their ``split``; only TRAIN updates weights, VAL
            picks the best epoch, TEST gives ``TrainResult.metrics``.
        cfg: epochs, batch size, learning rate, width … (``profile.train``).
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

    Ctrl-C (KeyboardInterrupt) ends training after the last finished epoch: the
    result holds the best weights so far and ``interrupted=True``. An interrupt
    before the first epoch finishes has nothing to keep and is re-raised.
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
    device = torch.device(device) if device is not None else default_device()
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    model = DGTNet(vehicles, width=cfg.width, fc_hidden=cfg.fc_hidden, rgb_weights=rgb_weights)
    model.set_normalization(*channel_statistics(dataset.patches, train_idx))
    model.to(device)
    columns = _head_columns(model, dataset.vehicle)  # (N,) model column per sample
    optimizer = torch.optim.Adam(model.parameters(), lr=cfg.learning_rate,
                                 weight_decay=cfg.weight_decay)
    labels = torch.from_numpy(dataset.labels.astype(np.float32))
    heads = torch.from_numpy(columns)

    history: list[dict[str, float]] = []
    best_state: dict[str, torch.Tensor] | None = None
    best_epoch, best_val, interrupted = 0, float("inf"), False
    name = "multi-task" if len(vehicles) > 1 else f"single-task {vehicles[0]}"
    epochs_bar = tqdm(range(1, cfg.epochs + 1), desc=f"train {name}", unit="epoch",
                      disable=not progress)
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
                loss = masked_loss(model(x), labels[idx].to(device), heads[idx].to(device))
                optimizer.zero_grad(set_to_none=True)
                loss.backward()
                optimizer.step()
                value = loss.item()
                total += value * len(idx)
                seen += len(idx)
                batch_bar.set_postfix(loss=f"{total / seen:.4f}")
                if on_batch_end is not None:
                    on_batch_end(epoch, step, value)
            batch_bar.close()
            val = _validation_loss(model, dataset, val_idx, columns, 1024, device)
            history.append({"epoch": epoch, "train_loss": total / seen, "val_loss": val,
                            "seconds": time.perf_counter() - t0})
            if val < best_val:
                best_val, best_epoch = val, epoch
                best_state = {k: v.detach().to("cpu", copy=True)
                              for k, v in model.state_dict().items()}
                if checkpoint_path is not None:  # the model holds the best weights right now
                    save_checkpoint(checkpoint_path, TrainResult(
                        model, copy.deepcopy(history), best_epoch, {}, False, cfg, seed))
            epochs_bar.set_postfix(train=f"{total / seen:.4f}", val=f"{val:.4f}",
                                   best=best_epoch)
            if cfg.patience is not None and epoch - best_epoch >= cfg.patience:
                break
    except KeyboardInterrupt:
        if best_state is None:
            raise
        interrupted = True
        tqdm.write(f"[dgt] training interrupted: keeping epoch {best_epoch} "
                   f"(val loss {best_val:.4f})")
    finally:
        if batch_bar is not None:
            batch_bar.close()
        epochs_bar.close()
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


# ── checkpoints ──────────────────────────────────────────────────────────────


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
) -> TrainResult:
    """Read a checkpoint (a ``.pt`` path or the dict of :func:`checkpoint_dict`).

    ``vehicles`` and ``architecture`` (e.g. ``DGTNet(...).architecture()``) are what
    the caller expects; a checkpoint of another vehicle set or architecture raises
    :class:`~dgt_lib.model.ArchitectureMismatchError` saying what differs. Something
    that is not a DGTNet checkpoint raises :class:`CheckpointError`.
    """
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
    model = DGTNet(arch["vehicles"], width=arch["width"], fc_hidden=arch["fc_hidden"])
    try:
        model.load_state_dict(ckpt["state_dict"])
    except RuntimeError as exc:
        raise ArchitectureMismatchError(f"{where}: weights do not fit {arch}: {exc}") from exc
    model.rgb_pretrained = bool(ckpt.get("rgb_pretrained", False))
    model.to(device).eval()
    cfg = TrainConfig(**ckpt["train_config"]) if ckpt.get("train_config") else None
    return TrainResult(model=model, history=ckpt["history"], best_epoch=ckpt["best_epoch"],
                       metrics=ckpt["metrics"], interrupted=ckpt["interrupted"], config=cfg,
                       seed=ckpt.get("seed"))


# ── cached models ────────────────────────────────────────────────────────────


def parse_kind(kind: str) -> tuple[str, ...]:
    """``"multitask"`` → all vehicles; ``"single:<vehicle>"`` → that one vehicle."""
    if kind == "multitask":
        return VEHICLES
    prefix, _, vehicle = kind.partition(":")
    if prefix == "single" and vehicle in VEHICLES:
        return (vehicle,)
    raise ValueError(f"unknown model kind {kind!r}; valid: {', '.join(MODEL_KINDS)}")


def model_relpath(kind: str) -> Path:
    """Where model ``kind`` lives under ``data/<profile>/``: ``models/single_vw_van.pt`` …"""
    parse_kind(kind)
    return Path("models") / f"{kind.replace(':', '_')}.pt"


def dataset_fingerprint(dataset: PatchDataset) -> str:
    """A hash of every array of ``dataset`` (what a cached model was trained on)."""
    return artifacts.config_hash(dataset.to_arrays())


def default_rgb_weights() -> Path | None:
    """torchvision's ResNet-18 ImageNet file if the user has it, else None.

    Looked for at ``$DGT_RESNET18_WEIGHTS``, then ``data/resnet18-f37072fd.pth``.
    """
    env = os.environ.get(RGB_WEIGHTS_ENV_VAR)
    candidates = ([Path(env)] if env else []) + [artifacts.data_root() / RGB_WEIGHTS_FILE]
    return next((p for p in candidates if p.is_file()), None)


class _Interrupted(Exception):
    def __init__(self, result: TrainResult) -> None:
        super().__init__("training interrupted")
        self.result = result


def ensure_model(
    profile: Profile,
    dataset: PatchDataset,
    kind: str = "multitask",
    *,
    seed: int | None = None,
    device: str | torch.device | None = None,
    progress: bool = True,
    rgb_weights: str | Path | None = None,
    dataset_hash: str | None = None,
) -> TrainResult:
    """The trained model ``kind`` of ``profile`` from the artifact cache, trained if needed.

    Stored at ``data/<profile>/models/<kind>.pt`` (``single:vw_van`` → ``single_vw_van.pt``);
    the configuration hash covers the dataset (``dataset_hash``, default
    :func:`dataset_fingerprint`), ``profile.train`` (architecture and training
    settings), the kind, the seed (default ``profile.seed``) and whether ImageNet
    RGB weights were used (``rgb_weights``, default :func:`default_rgb_weights`,
    only with width 64). While training, the best model so far is kept in
    ``<kind>.partial.pt``; on Ctrl-C that file remains, nothing enters the cache,
    and the best model so far is returned (``interrupted=True``).
    """
    vehicles = parse_kind(kind)
    cfg = profile.train
    seed = profile.seed if seed is None else seed
    if rgb_weights is None and cfg.width == 64:
        rgb_weights = default_rgb_weights()
    rgb = None
    if rgb_weights is not None:
        rgb = {"file": Path(rgb_weights).name, "bytes": Path(rgb_weights).stat().st_size}
    relpath = model_relpath(kind)
    partial = artifacts.profile_dir(profile.name) / relpath.with_suffix(".partial.pt")
    config = {"stage": "train", "kind": kind, "vehicles": list(vehicles),
              "dataset": dataset_hash or dataset_fingerprint(dataset), "train": cfg,
              "seed": seed, "rgb_weights": rgb, "checkpoint_version": CHECKPOINT_VERSION}

    def build() -> dict[str, Any]:
        result = train_model(dataset, cfg, vehicles=vehicles, seed=seed, device=device,
                             progress=progress, rgb_weights=rgb_weights,
                             checkpoint_path=partial)
        if result.interrupted:
            raise _Interrupted(result)
        return checkpoint_dict(result)

    try:
        ckpt = artifacts.ensure(relpath, config, build, profile=profile.name)
    except _Interrupted as stop:
        print(f"[dgt] {kind}: interrupted; best model so far kept in {partial} "
              f"(not cached: a rerun trains again)")
        return stop.result
    partial.unlink(missing_ok=True)
    return load_checkpoint(ckpt, vehicles=vehicles,
                           device=device if device is not None else default_device())


def models_stage(profile: Profile, dataset: PatchDataset,
                 kinds: tuple[str, ...] = MODEL_KINDS, progress: bool = True) -> StageOutput:
    """The training stage of ``dgt reproduce``: every model of ``kinds``, through the cache.

    Returns the checkpoint paths and a summary with each model's test MSE and
    Spearman ρ per vehicle. A single-task model whose vehicle has no training or
    no validation samples (possible in the tiny ``smoke`` profile) is skipped,
    and the summary says so.
    """
    paths, parts = [], []
    counts = dataset.counts()
    for kind in kinds:
        vehicles = parse_kind(kind)
        if len(vehicles) == 1 and min(counts[vehicles[0]]["train"], counts[vehicles[0]]["val"]) < 1:
            parts.append(f"{kind} skipped (no train or val samples: {counts[vehicles[0]]})")
            print(f"[dgt] {parts[-1]}")
            continue
        result = ensure_model(profile, dataset, kind, progress=progress)
        paths.append(artifacts.profile_dir(profile.name) / model_relpath(kind))
        scores = ", ".join(f"{v} mse {m['mse']:.3f} ρ {m['spearman']:.2f}"
                           for v, m in result.metrics.items())
        parts.append(f"{kind} (best epoch {result.best_epoch}: {scores})")
        for v in collapsed_heads(result.metrics):
            parts[-1] += f" — {v} head COLLAPSED (constant L̂)"
            m = result.metrics[v]
            print(f"[dgt] warning: {kind}: the {v} head predicts a near-constant L̂ "
                  f"(std {m['pred_std']:.1e} against the labels' {m['label_std']:.2f})")
    return StageOutput(paths, "; ".join(parts))


# ── synthetic data (tests, benchmarks, teaching) ─────────────────────────────

SYNTHETIC_MAX_SLOPE = {"jeep": 0.45, "vw_van": 0.25, "mercedes_van": 0.2, "carla_cola": 0.1}
"""Synthetic rule: the uphill slope (rise/run) at which a vehicle's L falls to 0.5."""
SYNTHETIC_ROUGHNESS_SCALE = {"jeep": 0.6, "vw_van": 0.4, "mercedes_van": 0.15, "carla_cola": 0.3}
"""Synthetic rule: roughness σ_H (m) that multiplies a vehicle's L by e^-1."""


def synthetic_dataset(
    n_per_vehicle: tuple[int, int, int, int] = (300, 100, 100, 20),
    seed: int = 0,
    patches_per_trajectory: int = 10,
) -> PatchDataset:
    """Synthetic patches whose label follows slope and roughness differently per vehicle.

    Each patch is a plane of forward slope s ∈ [−0.6, 0.6] (positive = uphill:
    the height rises toward row 0) with roughness σ ∈ [0, 0.4] m, random colours.
    Vehicle v's label is L_v = sigmoid((s_max,v − s)/0.05) · exp(−σ / r_v) plus
    noise (±0.02), clipped to [0, 1], with ``SYNTHETIC_MAX_SLOPE`` and
    ``SYNTHETIC_ROUGHNESS_SCALE``. Split 70/15/15 by trajectory (groups of
    ``patches_per_trajectory``). Not data from the simulator: for tests and speed.
    """
    rng = np.random.default_rng(seed)
    n = int(sum(n_per_vehicle))
    vehicle = np.repeat(np.arange(len(VEHICLES), dtype=np.int8), n_per_vehicle)
    slope = rng.uniform(-0.6, 0.6, n)
    rough = rng.uniform(0.0, 0.4, n)
    rows = (21 - np.arange(22)) * 0.4  # (22,) distance behind the patch's front row, m
    patches = np.empty((n, N_CHANNELS, 22, 7), dtype=np.float16)
    patches[:, 0:3] = np.clip(rng.uniform(0.2, 0.6, (n, 3, 1, 1))
                              + rng.normal(0, 0.05, (n, 3, 22, 7)), 0, 1)
    height = (slope[:, None] * rows[None, :])[:, :, None] + rng.uniform(-2, 2, (n, 1, 1))
    patches[:, 3] = height + rough[:, None, None] * rng.normal(0, 0.3, (n, 22, 7))
    patches[:, 4] = rough[:, None, None] * (1 + rng.normal(0, 0.1, (n, 22, 7)))
    patches[:, 5] = np.abs(slope)[:, None, None] + rng.normal(0, 0.02, (n, 22, 7))
    s_max = np.array([SYNTHETIC_MAX_SLOPE[v] for v in VEHICLES])[vehicle]
    r_v = np.array([SYNTHETIC_ROUGHNESS_SCALE[v] for v in VEHICLES])[vehicle]
    labels = np.exp(-rough / r_v) / (1 + np.exp((slope - s_max) / 0.05))
    labels = np.clip(labels + rng.normal(0, 0.02, n), 0, 1).astype(np.float32)
    trajectory = (np.arange(n) // patches_per_trajectory).astype(np.int32)
    # keep each trajectory within one vehicle
    trajectory = (trajectory + vehicle.astype(np.int32) * (n + 1)).astype(np.int32)
    pose = np.column_stack([rng.uniform(0, 100, (n, 2)), rng.uniform(0, 2 * np.pi, n)])
    return PatchDataset(
        patches=patches, observed=np.ones((n, 22, 7), dtype=bool), labels=labels,
        vehicle=vehicle, trajectory=trajectory, pose=pose.astype(np.float32),
        split=split_by_trajectory(trajectory, vehicle, seed=seed),
    )


def stage_train(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: the multi-task model and one single-task model per vehicle."""
    from .dataset import ensure_dataset

    return models_stage(profile, ensure_dataset(profile))
