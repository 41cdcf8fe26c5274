"""The training stage of a cached run, timed on another device (a GPU): the same code, data
and settings as ``dgt reproduce``'s ``train`` stage, side by side with the cached run's models.

On a machine with the run's cache (``data/<profile>/seed-<s>/``) and a GPU::

    .venv/bin/python benchmarks/bench_train_stage.py --profile paper --seed 0

A GPU machine without the cache gets a packed copy of the dataset: the training world's
BEV, the dataset's arrays but its patches (which are cut again from the BEV at their poses,
:func:`~dgt_lib.perception.patches.extract_patches`) and the float16 values that the cut at
the stored float32 poses rounds differently — 14 MB for ``paper`` instead of 122 MB, checked
on arrival against the dataset's fingerprint, so the GPU trains on the same patches bit for
bit::

    .venv/bin/python benchmarks/bench_train_stage.py --profile paper --seed 0 --pack DIR
    python benchmarks/bench_train_stage.py --packed DIR          # on the GPU machine

The stage trains every model of :data:`~dgt_lib.stages.train.MODEL_KINDS` through
:func:`~dgt_lib.stages.train.models_stage` into a scratch data directory (the cache is never
touched) and prints, per model, the epochs, best epoch, seconds per epoch and test MSE and
Spearman ρ per vehicle, beside the cached models' (trained where the cache was made).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.perception.bev import BEVMap
from dgt_lib.perception.dataset import PatchDataset
from dgt_lib.perception.patches import extract_patches
from dgt_lib.stages.train import MODEL_KINDS, dataset_fingerprint, model_relpath

MANIFEST = "manifest.json"


def cut_patches(bev: BEVMap, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The dataset's patches cut again at its stored poses: (N, 6, 22, 7) float16 and the
    (N, 22, 7) observed mask, as :func:`~dgt_lib.perception.dataset.build_dataset` stores them."""
    patches, observed = extract_patches(bev, np.asarray(pose, np.float64))
    return patches.astype(np.float16), observed


def cached_models(profile) -> dict[str, dict]:
    """Epochs, seconds, best epoch and test metrics of the cached models (nothing trained)."""
    from dgt_lib.stages.paths import data_dir

    out = {}
    for kind in MODEL_KINDS:
        path = data_dir(profile) / model_relpath(kind)
        if path.exists():
            ckpt = artifacts.load(path)
            out[kind] = {"history": ckpt["history"], "best_epoch": ckpt["best_epoch"],
                         "metrics": ckpt["metrics"]}
    return out


def cached_stage_seconds(profile) -> float | None:
    """The training stage's wall time in the latest run that recorded it for this seed."""
    from dgt_lib.stages.timings import read_stage_times

    times = [r["seconds"] for r in read_stage_times(profile.name)
             if r["seed"] == profile.seed and r["stage"] == "train" and r["seconds"] > 60]
    return times[-1] if times else None


def write_pack(dataset: PatchDataset, bev: BEVMap, out: Path, manifest: dict) -> int:
    """Write ``dataset``, whose patches were cut from ``bev``, compactly to ``out``: the BEV,
    the dataset's arrays but patches and mask, and the patch values that cutting again at the
    stored poses rounds differently. ``manifest`` (JSON-able) is stored beside them with the
    dataset's fingerprint. Returns how many float16 values had to be stored."""
    patches, observed = cut_patches(bev, dataset.pose)
    if patches.shape != dataset.patches.shape or not np.array_equal(observed, dataset.observed):
        raise ValueError("the dataset's patches were not cut from this BEV map at its poses")
    flat_new = patches.view(np.uint16).ravel()
    flat_old = dataset.patches.view(np.uint16).ravel()
    fix = np.flatnonzero(flat_new != flat_old)
    out.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out / "bev_training.npz", **bev.to_arrays())
    rest = {k: v for k, v in dataset.to_arrays().items() if k not in ("patches", "observed")}
    np.savez_compressed(out / "dataset_rest.npz", fix_index=fix, fix_value=flat_old[fix], **rest)
    (out / MANIFEST).write_text(json.dumps({**manifest,
                                            "fingerprint": dataset_fingerprint(dataset)}))
    return len(fix)


def read_pack(packed: Path) -> tuple[PatchDataset, dict]:
    """The dataset and manifest of a :func:`write_pack` directory, checked against the
    fingerprint: the same arrays, bit for bit, or a ``ValueError``."""
    manifest = json.loads((packed / MANIFEST).read_text())
    bev = BEVMap.from_arrays(dict(np.load(packed / "bev_training.npz")))
    rest = dict(np.load(packed / "dataset_rest.npz"))
    patches, observed = cut_patches(bev, rest["pose"])
    flat = patches.view(np.uint16).reshape(-1)
    flat[rest.pop("fix_index")] = rest.pop("fix_value")
    dataset = PatchDataset.from_arrays({**rest, "patches": patches, "observed": observed})
    if dataset_fingerprint(dataset) != manifest["fingerprint"]:
        raise ValueError(f"{packed}: the rebuilt dataset's fingerprint differs from the packed one")
    return dataset, manifest


def pack(profile, out: Path) -> None:
    """Pack the run's cached dataset, with the cached models' records, into ``out``."""
    from dgt_lib.stages.collect import ensure_bev
    from dgt_lib.stages.dataset import ensure_dataset

    dataset = ensure_dataset(profile, progress=False)
    bev = ensure_bev("training", profile, progress=False)
    n_fix = write_pack(dataset, bev, out, {
        "profile": profile.name, "seed": profile.seed,
        "cached_models": cached_models(profile),
        "cached_stage_seconds": cached_stage_seconds(profile),
        "cached_on": f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs"})
    size = sum(p.stat().st_size for p in out.iterdir()) / 1e6
    print(f"packed {len(dataset)} patches into {out} ({size:.1f} MB); {n_fix} float16 values "
          f"of {dataset.patches.size:,} are stored because the cut rounds them differently")


def summary_row(name: str, history: list[dict], best_epoch: int, metrics: dict) -> str:
    seconds = sum(h["seconds"] for h in history)
    scores = "; ".join(f"{v} {m['mse']:.4f} / {m['spearman']:.2f}" for v, m in metrics.items())
    return (f"| {name} | {len(history)} | {best_epoch} | {seconds:.0f} | "
            f"{seconds / len(history):.1f} | {scores} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="paper")
    parser.add_argument("--seed", type=int, default=0, help="the run seed whose dataset trains")
    parser.add_argument("--pack", type=Path, help="only write the packed dataset here")
    parser.add_argument("--packed", type=Path, help="train on a packed dataset (no cache)")
    parser.add_argument("--progress", action="store_true", help="tqdm bars per epoch")
    args = parser.parse_args()
    if args.packed:
        manifest = json.loads((args.packed / MANIFEST).read_text())
        args.profile, args.seed = manifest["profile"], manifest["seed"]
    profile = get_profile(args.profile).with_(seed=args.seed)
    if args.pack:
        pack(profile, args.pack)
        return
    t0 = time.perf_counter()
    if args.packed:
        dataset, manifest = read_pack(args.packed)
    else:
        from dgt_lib.stages.dataset import ensure_dataset

        dataset = ensure_dataset(profile, progress=False)
        manifest = {"cached_models": cached_models(profile),
                    "cached_stage_seconds": cached_stage_seconds(profile)}
    print(f"{profile.name} seed {profile.seed}: {len(dataset)} patches, loaded and checked in "
          f"{time.perf_counter() - t0:.1f} s")

    import torch

    from dgt_lib.stages.train import models_stage

    device = (torch.cuda.get_device_name(0) if torch.cuda.is_available()
              else f"CPU, {torch.get_num_threads()} torch threads")
    print(f"torch {torch.__version__} on {device}; load average {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory() as scratch:
        os.environ[artifacts.DATA_ENV_VAR] = scratch  # never train into the real cache
        t0 = time.perf_counter()
        models_stage(profile, dataset, progress=args.progress)
        stage_s = time.perf_counter() - t0
        fresh = cached_models(profile)
    print(f"\ntraining stage: {stage_s:.1f} s on {device} (the cached run's: "
          f"{manifest.get('cached_stage_seconds') or 'not recorded'} s)\n")
    print("| model | epochs | best | train + val s | s / epoch | test MSE / ρ per vehicle |")
    print("| --- | --- | --- | --- | --- | --- |")
    for kind in MODEL_KINDS:
        for where, models in (("here", fresh), ("cached", manifest["cached_models"])):
            if kind in models:
                m = models[kind]
                print(summary_row(f"{kind} ({where})", m["history"], m["best_epoch"],
                                  m["metrics"]))


if __name__ == "__main__":
    main()
