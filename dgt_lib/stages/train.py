"""Stage ``train``: the multi-task model and one single-task model per vehicle, cached
(paper: Multi-Task Learning, Baselines → DGT-Map(ST)).

The training itself is :func:`dgt_lib.learning.run.train_model`; this module keys
each model by what determines it (dataset, settings, seed) and stores it under
``models/<kind>.pt``.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Any

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, Profile, TrainConfig
from dgt_lib.learning.checkpoints import (
    CHECKPOINT_VERSION,
    TrainResult,
    checkpoint_dict,
    load_checkpoint,
    prediction_digest,
)
from dgt_lib.perception.dataset import PatchDataset
from dgt_lib.stages.dataset import dataset_fingerprint, ensure_dataset
from dgt_lib.stages.output import StageOutput
from dgt_lib.stages.paths import cache_dir, data_dir

MODEL_KINDS: tuple[str, ...] = ("multitask",) + tuple(f"single:{v}" for v in VEHICLES)
"""The models of ``ensure_model``: multi-task, and one single-task model per vehicle."""

SNAPSHOT_EVERY_S = 60.0
"""Least wall time between two snapshots of an unfinished training [s]
(``train_model(snapshot_every_s=…)``)."""

RGB_WEIGHTS_ENV_VAR = "DGT_RESNET18_WEIGHTS"
RGB_WEIGHTS_FILE = "resnet18-f37072fd.pth"
"""torchvision's ImageNet ResNet-18 file name; looked for under ``data/`` by ``ensure_model``."""


def parse_kind(kind: str) -> tuple[str, ...]:
    """``"multitask"`` → all vehicles; ``"single:<vehicle>"`` → that one vehicle."""
    if kind == "multitask":
        return VEHICLES
    prefix, _, vehicle = kind.partition(":")
    if prefix == "single" and vehicle in VEHICLES:
        return (vehicle,)
    raise ValueError(f"unknown model kind {kind!r}; valid: {', '.join(MODEL_KINDS)}")


def inputs_suffix(inputs: str = "rgbd") -> str:
    """What a model's and its costmaps' file names add for ``TrainConfig.inputs``: nothing
    for ``rgbd``, else ``_<inputs>`` (``_geometry``), so a model that reads other channels
    is cached beside the RGB-D one instead of replacing it."""
    return "" if inputs == "rgbd" else f"_{inputs}"


def model_relpath(kind: str, inputs: str = "rgbd") -> Path:
    """Where model ``kind`` reading ``inputs`` lives in the profile's data directory:
    ``models/single_vw_van.pt``, ``models/multitask_geometry.pt`` …"""
    parse_kind(kind)
    return Path("models") / f"{kind.replace(':', '_')}{inputs_suffix(inputs)}.pt"


def snapshot_relpath(kind: str, inputs: str = "rgbd") -> Path:
    """Where model ``kind``'s unfinished training is kept between runs
    (:mod:`dgt_lib.learning.resume`): ``models/single_vw_van.resume.pt`` …"""
    return model_relpath(kind, inputs).with_suffix(".resume.pt")


def default_rgb_weights() -> Path | None:
    """torchvision's ResNet-18 ImageNet file if the user has it, else None.

    Looked for at ``$DGT_RESNET18_WEIGHTS``, then ``data/resnet18-f37072fd.pth``.
    """
    env = os.environ.get(RGB_WEIGHTS_ENV_VAR)
    candidates = ([Path(env)] if env else []) + [artifacts.data_root() / RGB_WEIGHTS_FILE]
    return next((p for p in candidates if p.is_file()), None)


def rgb_weights_for(cfg: TrainConfig) -> Path | None:
    """The ImageNet RGB weights a training of ``cfg`` starts from:
    :func:`default_rgb_weights` for width 64 (the ResNet-18 they fit), else None."""
    return default_rgb_weights() if cfg.width == 64 else None


def model_config(profile: Profile, dataset: PatchDataset | None, kind: str = "multitask", *,
                 dataset_hash: str | None = None) -> dict[str, Any]:
    """What model ``kind`` of ``profile`` depends on (its artifact's cache key): the
    dataset (``dataset_hash``, default :func:`dataset_fingerprint`), ``profile.train`` (its
    settings at their defaults left out, :mod:`dgt_lib.core.cache_keys`), the kind,
    ``profile.seed``, whether ImageNet RGB weights were used (:func:`rgb_weights_for`) and
    the checkpoint layout. Computed without torch."""
    vehicles = parse_kind(kind)
    cfg = profile.train
    rgb_weights = rgb_weights_for(cfg)
    rgb = None
    if rgb_weights is not None:
        rgb = {"file": Path(rgb_weights).name, "bytes": Path(rgb_weights).stat().st_size}
    return {"stage": "train", "kind": kind, "vehicles": list(vehicles),
            "dataset": dataset_hash or dataset_fingerprint(dataset), "train": cfg,
            "seed": profile.seed, "rgb_weights": rgb,
            "checkpoint_version": CHECKPOINT_VERSION}


def ensure_model(
    profile: Profile,
    dataset: PatchDataset,
    kind: str = "multitask",
    *,
    progress: bool = True,
    dataset_hash: str | None = None,
) -> TrainResult:
    """The trained model ``kind`` of ``profile`` from the artifact cache, trained if needed.

    Stored at ``models/<kind>.pt`` (``single:vw_van`` → ``single_vw_van.pt``; a model of
    other ``train.inputs`` than RGB-D beside it: :func:`model_relpath`), keyed by
    :func:`model_config` (the dataset, ``profile.train``, the kind, the seed, the RGB
    weights). The artifact's fingerprint, which keys the costmaps and
    experiments built on the model, is its
    :func:`~dgt_lib.learning.checkpoints.prediction_digest`: retraining to the same
    weights invalidates nothing built on it. Ctrl-C (KeyboardInterrupt) while training
    propagates at once: an interrupted model is never cached as a finished one, but its
    progress is kept: after an epoch (at most every :data:`SNAPSHOT_EVERY_S`) the
    training is saved in ``models/<kind>.resume.pt`` (:func:`snapshot_relpath`), and the
    next call resumes after that epoch, to the same weights as a training never stopped
    (on the CPU; a GPU's cuDNN kernels differ from run to run anyway; an interrupt or a crash
    loses at most the time since). The snapshot is deleted once
    the model is cached.

    The model trains and is returned on ``profile.execution.device`` (a CUDA GPU when there
    is one); not part of the cache key — a checkpoint holds CPU tensors and loads on any
    device.
    """
    from dgt_lib.learning.run import train_model  # torch: only here
    from dgt_lib.learning.training import resolve_device

    vehicles = parse_kind(kind)
    device = resolve_device(profile.execution.device)
    cfg = profile.train
    config = model_config(profile, dataset, kind, dataset_hash=dataset_hash)
    snapshot = data_dir(profile) / snapshot_relpath(kind, cfg.inputs)

    def build() -> dict[str, Any]:
        return checkpoint_dict(train_model(
            dataset, cfg, vehicles=vehicles, seed=profile.seed, device=device,
            progress=progress, rgb_weights=rgb_weights_for(cfg), keep_best_on_interrupt=False,
            snapshot_path=snapshot, snapshot_key=config, snapshot_every_s=SNAPSHOT_EVERY_S))

    ckpt = artifacts.ensure(model_relpath(kind, cfg.inputs), config, build,
                            profile=cache_dir(profile), fingerprint=prediction_digest)
    snapshot.unlink(missing_ok=True)
    return load_checkpoint(ckpt, vehicles=vehicles, device=device)


def model_digest(profile: Profile, dataset: PatchDataset | None, kind: str = "multitask", *,
                 dataset_hash: str | None = None, progress: bool = True) -> str:
    """The digest that keys what is built on model ``kind`` (its
    :func:`~dgt_lib.learning.checkpoints.prediction_digest`, from the cache's metadata).
    A cached model is checked against :func:`model_config` but not loaded (no torch: a
    cached ``dgt plan`` stays quick); a missing or stale one is trained first
    (:func:`ensure_model`). ``dataset_hash``: :func:`dataset_fingerprint` of ``dataset``
    when the caller has it; with it, ``dataset`` may be None, and the profile's dataset is
    loaded only if the model must be trained."""
    if dataset is None and dataset_hash is None:
        raise ValueError("model_digest needs the dataset or its dataset_hash")
    config = model_config(profile, dataset, kind, dataset_hash=dataset_hash)
    relpath = model_relpath(kind, profile.train.inputs)
    if not artifacts.is_fresh(relpath, config, profile=cache_dir(profile)):
        if dataset is None:
            dataset = ensure_dataset(profile, progress=progress)
        ensure_model(profile, dataset, kind, dataset_hash=dataset_hash, progress=progress)
    return artifacts.stored_digest(relpath, profile=cache_dir(profile))


def models_stage(profile: Profile, dataset: PatchDataset,
                 kinds: tuple[str, ...] = MODEL_KINDS, progress: bool = True) -> StageOutput:
    """The training stage of ``dgt reproduce``: every model of ``kinds``, through the cache.

    Returns the checkpoint paths and a summary with each model's test MSE and
    Spearman ρ per vehicle. A single-task model whose vehicle has no training or
    no validation samples (possible in the tiny ``smoke`` profile) is skipped,
    and the summary says so. Ctrl-C propagates (:func:`ensure_model`): the models
    finished before it stay cached, the interrupted one resumes from its last snapshot.
    """
    from dgt_lib.learning.training import collapsed_heads

    paths, parts = [], []
    counts = dataset.counts()
    for kind in kinds:
        vehicles = parse_kind(kind)
        if len(vehicles) == 1 and min(counts[vehicles[0]]["train"], counts[vehicles[0]]["val"]) < 1:
            parts.append(f"{kind} skipped (no train or val samples: {counts[vehicles[0]]})")
            print(f"[dgt] {parts[-1]}")
            continue
        with warnings.catch_warnings():  # said once, below, trained now or read from the cache
            warnings.filterwarnings("ignore", message=".*near-constant L̂")
            result = ensure_model(profile, dataset, kind, progress=progress)
        paths.append(data_dir(profile) / model_relpath(kind, profile.train.inputs))
        scores = ", ".join(f"{v} mse {m['mse']:.3f} ρ {m['spearman']:.2f}"
                           for v, m in result.metrics.items())
        parts.append(f"{kind} (best epoch {result.best_epoch}: {scores})")
        for v in collapsed_heads(result.metrics):
            parts[-1] += f" — {v} head COLLAPSED (constant L̂)"
            m = result.metrics[v]
            print(f"[dgt] warning: {kind}: the {v} head predicts a near-constant L̂ "
                  f"(std {m['pred_std']:.1e} against the labels' {m['label_std']:.2f})")
    return StageOutput(paths, "; ".join(parts))


def cached_model_metrics(profile: Profile) -> dict[str, dict[str, dict[str, float]]]:
    """Test metrics ``{kind: {vehicle: metrics}}`` of every model of the profile's run seed
    that is in the cache (nothing is trained): what the results report prints."""
    out = {}
    for kind in MODEL_KINDS:
        path = data_dir(profile) / model_relpath(kind, profile.train.inputs)
        if path.exists():
            out[kind] = artifacts.load(path)["metrics"]
    return out


def stage_train(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: the multi-task model and one single-task model per vehicle."""
    return models_stage(profile, ensure_dataset(profile))
