"""Training and inference speed of DGTNet per width, and the accuracy each width reaches.

    .venv/bin/python benchmarks/bench_train.py                  # speed, widths 64 32 16
    .venv/bin/python benchmarks/bench_train.py --accuracy       # + synthetic accuracy per width
    .venv/bin/python benchmarks/bench_train.py --full-epoch     # + one real epoch at width 64
    .venv/bin/python benchmarks/bench_train.py --conv-taps all live --full-epoch
    .venv/bin/python benchmarks/bench_train.py --no-speed --accuracy --threads 1
    .venv/bin/python benchmarks/bench_train.py --widths 64 --bf16   # + mixed precision

Speed uses a synthetic dataset of the paper's size (30k/10k/10k/2k patches,
float16, split 70/15/15 by trajectory): training samples/s are timed over
``--steps`` Adam steps of the real training step (float16 batch → float32,
masked loss), and an epoch's time is extrapolated as train samples / rate plus
validation patches / inference rate. Inference is ``predict`` at batch 1024
(all heads from one embedding). ``--conv-taps all live`` times each width both with every
kernel tap and with the live taps only (``TrainConfig.conv_taps``: the same network,
fewer multiplications of zero padding). ``--accuracy`` trains each width on a smaller
synthetic set with the same seed and reports test MSE and Spearman per vehicle
(synthetic labels: a proxy for the accuracy trade-off, not the simulator's).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import torch

from dgt_lib.core.config import CONV_TAPS, VEHICLES, TrainConfig
from dgt_lib.learning.model import DGTNet, count_parameters
from dgt_lib.learning.synthetic import synthetic_dataset
from dgt_lib.learning.training import (
    batch_to_tensor,
    channel_statistics,
    masked_loss,
    predict,
    train_model,
)
from dgt_lib.perception.dataset import TRAIN, VAL

PAPER_SIZES = (30_000, 10_000, 10_000, 2_000)  # paper: Experiments → Dataset


def train_rate(dataset, width: int, batch_size: int, steps: int, seed: int = 0,
               conv_taps: str = "all", bf16: bool = False) -> float:
    """Training samples per second of ``steps`` Adam steps (after 2 warm-up steps);
    ``bf16``: the forward pass under ``torch.autocast`` in bfloat16 (mixed precision,
    float32 weights) with channels-last tensors — what AMX CPUs run fastest."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    model = DGTNet(width=width)
    model.use_live_taps(conv_taps == "live")
    train_idx = np.flatnonzero(dataset.split == TRAIN)
    model.set_normalization(*channel_statistics(dataset.patches, train_idx[:4096]))
    model.train()
    if bf16:
        model = model.to(memory_format=torch.channels_last)
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    labels = torch.from_numpy(dataset.labels)
    heads = torch.from_numpy(dataset.vehicle.astype(np.int64))
    t0 = 0.0
    for step in range(steps + 2):
        if step == 2:
            t0 = time.perf_counter()
        idx = rng.choice(train_idx, batch_size, replace=False)
        x = batch_to_tensor(dataset.patches[idx], torch.device("cpu"))
        if bf16:
            with torch.autocast("cpu", dtype=torch.bfloat16):
                pred = model(x.contiguous(memory_format=torch.channels_last)).float()
        else:
            pred = model(x)
        loss = masked_loss(pred, labels[idx], heads[idx])
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
    return steps * batch_size / (time.perf_counter() - t0)


def inference_rate(dataset, width: int, n: int, batch_size: int = 1024) -> float:
    """Patches per second of ``predict`` (eval mode, no grad, all heads) on ``n`` patches."""
    model = DGTNet(width=width).eval()
    predict(model, dataset.patches[:batch_size], batch_size)  # warm-up
    t0 = time.perf_counter()
    predict(model, dataset.patches[:n], batch_size)
    return n / (time.perf_counter() - t0)


def speed(args: argparse.Namespace) -> None:
    t0 = time.perf_counter()
    ds = synthetic_dataset(PAPER_SIZES, seed=0, patches_per_trajectory=75)
    n_train = int(np.sum(ds.split == TRAIN))
    n_val = int(np.sum(ds.split == VAL))
    print(f"synthetic paper-sized dataset: {len(ds)} patches ({n_train} train, {n_val} val), "
          f"built in {time.perf_counter() - t0:.1f} s")
    print(f"{'width':>5} {'taps':>9} {'params':>10} {'train samples/s':>16} {'epoch (s)':>10} "
          f"{'infer patches/s':>16}")
    for width in args.widths:
        infer = inference_rate(ds, width, args.infer_patches)
        params = count_parameters(DGTNet(width=width))
        for taps in args.conv_taps:
            for bf16 in (False, True) if args.bf16 else (False,):
                rate = train_rate(ds, width, args.batch_size, args.steps, conv_taps=taps,
                                  bf16=bf16)
                epoch = n_train / rate + n_val / infer
                print(f"{width:>5} {taps + (' bf16' if bf16 else ''):>9} {params:>10,} "
                      f"{rate:>16.0f} {epoch:>10.0f} {infer:>16.0f}", flush=True)
    for taps in args.conv_taps if args.full_epoch else ():
        cfg = TrainConfig(epochs=1, batch_size=args.batch_size, width=64, conv_taps=taps)
        t0 = time.perf_counter()
        result = train_model(ds, cfg, seed=0, progress=True)
        print(f"one real epoch at width 64, {taps} taps (train + val + test metrics): "
              f"{time.perf_counter() - t0:.0f} s, val loss {result.history[0]['val_loss']:.4f}")


def accuracy(args: argparse.Namespace) -> None:
    ds = synthetic_dataset(args.accuracy_sizes, seed=1, patches_per_trajectory=25)
    print(f"\naccuracy on synthetic labels: {len(ds)} patches "
          f"({dict(zip(VEHICLES, args.accuracy_sizes, strict=True))}), "
          f"{args.accuracy_epochs} epochs, batch {args.batch_size}, seed 0")
    print(f"{'width':>5} {'train s':>8} {'best ep':>7} "
          + " ".join(f"{v + ' mse/ρ':>22}" for v in VEHICLES))
    for width in args.widths:
        cfg = TrainConfig(epochs=args.accuracy_epochs, batch_size=args.batch_size, width=width)
        t0 = time.perf_counter()
        r = train_model(ds, cfg, seed=0, progress=False)
        cells = " ".join(f"{r.metrics[v]['mse']:>12.4f}/{r.metrics[v]['spearman']:<9.3f}"
                         for v in VEHICLES)
        print(f"{width:>5} {time.perf_counter() - t0:>8.0f} {r.best_epoch:>7} {cells}",
              flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--widths", type=int, nargs="+", default=[64, 32, 16])
    parser.add_argument("--batch-size", type=int, default=256)
    parser.add_argument("--steps", type=int, default=20, help="timed training steps per width")
    parser.add_argument("--infer-patches", type=int, default=8192)
    parser.add_argument("--threads", type=int, default=None, help="torch threads (default: all)")
    parser.add_argument("--full-epoch", action="store_true")
    parser.add_argument("--conv-taps", nargs="+", choices=CONV_TAPS, default=["all"],
                        help="time training with every kernel tap and/or the live taps only")
    parser.add_argument("--bf16", action="store_true",
                        help="also time training with a bfloat16 autocast forward pass")
    parser.add_argument("--accuracy", action="store_true")
    parser.add_argument("--no-speed", action="store_true", help="skip the speed table")
    parser.add_argument("--accuracy-sizes", type=int, nargs=4, default=[3000, 1000, 1000, 200])
    parser.add_argument("--accuracy-epochs", type=int, default=6)
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    if not args.no_speed:
        speed(args)
    if args.accuracy:
        accuracy(args)


if __name__ == "__main__":
    main()
