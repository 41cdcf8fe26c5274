"""Directional costmap speed and accuracy: literal stride-1 procedure vs lattice vs dense,
and the densely evaluable PooledNet.

Targets: the lattice path — the K = 8 costmaps of all four
vehicles for a 400 × 400-cell map in ≤ 30 s on this 2-core machine, ≥ 10× faster than the
literal procedure, mean |ΔC| ≤ 0.02 from it; dense evaluation — ≤ 3 s for
width 64 (≥ 100× literal) at mean |ΔC| ≤ 0.01. Each row reports mean and max |ΔC|
from the literal procedure over all cells of the measured headings.

    .venv/bin/python benchmarks/bench_costmap.py [--size 400] [--literal-headings 8]
        [--model data/demo/models/multitask.pt] [--pooled data/pooled/pooled_demo_seed0.pt]

Without ``--model`` it trains a small model for a few seconds on synthetic
patches (``train.synthetic_dataset``) so that predictions depend on the terrain
the way a trained model's do; with ``--model`` it uses a real checkpoint. The
literal procedure costs the same for every heading, so ``--literal-headings N``
(< 8) measures N headings and scales the time to 8 (the difference is measured
on those N headings) — the table says so.

The "PooledNet" rows (:mod:`dgt_lib.beyond.pooled`, ``--pooled``: trained networks saved
by ``studies/eval_pooled.py``, else an untrained one per ``--pooled-widths``) are another
network, built to be evaluated densely: its own literal procedure (every window cut out
with its context and run on its own, ``--literal-headings`` as above) against its dense
evaluation, and the speed-up also against DGTNet's literal procedure of the same run.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

from dgt_lib.beyond.dense import directional_costmap_dense
from dgt_lib.beyond.pooled import PooledNet, bfloat16_copy
from dgt_lib.core.config import TrainConfig
from dgt_lib.core.geometry import GridSpec, heading_bins
from dgt_lib.learning.checkpoints import load_checkpoint
from dgt_lib.learning.run import train_model
from dgt_lib.learning.synthetic import synthetic_dataset
from dgt_lib.learning.training import predict, window_predictor
from dgt_lib.mapping.costmap import (
    _heading_layer,
    directional_costmap,
    field_heading_layer,
)
from dgt_lib.perception.bev import BEVMap, height_gradient


def terrain_bev(size: int, seed: int = 0) -> BEVMap:
    """A hilly synthetic BEV: smoothed noise hills, a few sharp bumps, grass-like colours."""
    rng = np.random.default_rng(seed)
    grid = GridSpec((0.0, 0.0), 0.4, (size, size))
    h = cv2.GaussianBlur(rng.normal(0, 1, (size, size)).astype(np.float32), (0, 0), 25) * 250
    bumps = np.zeros_like(h)
    for _ in range(size // 20):
        r, c = rng.integers(0, size, 2)
        bumps[max(r - 3, 0) : r + 3, max(c - 3, 0) : c + 3] = rng.uniform(0.3, 1.2)
    h = h + cv2.GaussianBlur(bumps, (0, 0), 1.5)
    observed = np.ones((size, size), bool)
    channels = np.zeros((6, size, size), np.float32)
    channels[0], channels[1], channels[2] = 0.3, 0.5 + 0.1 * np.tanh(h), 0.2
    channels[3] = h
    channels[4] = np.abs(cv2.Laplacian(h, cv2.CV_32F)) * 0.2
    channels[5] = height_gradient(h, observed, 0.4)
    return BEVMap(grid, channels, observed, np.ones((size, size), np.int64))


def make_model(width: int, checkpoint: str | None):
    if checkpoint:
        return load_checkpoint(checkpoint).model
    cfg = TrainConfig(epochs=2, batch_size=128, width=width)
    return train_model(synthetic_dataset((1500, 500, 500, 200)), cfg, seed=0, progress=False).model


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=400, help="map side [cells]")
    parser.add_argument("--literal-headings", type=int, default=8)
    parser.add_argument("--widths", type=int, nargs="+", default=[64, 32])
    parser.add_argument("--strides", default="6x3,4x2")
    parser.add_argument("--model", default=None, help="a checkpoint instead of a synthetic model")
    parser.add_argument("--pooled", nargs="+", default=[],
                        help="trained PooledNet state dicts (studies/eval_pooled.py)")
    parser.add_argument("--pooled-widths", type=int, nargs="*", default=[],
                        help="untrained PooledNets of these widths (timing only); default 32 "
                             "when no --pooled is given")
    parser.add_argument("--bf16", action="store_true",
                        help="also time each PooledNet in bfloat16 (pooled.bfloat16_copy)")
    args = parser.parse_args()
    torch.set_num_threads(os.cpu_count() or 2)
    bev = terrain_bev(args.size)
    strides = [tuple(int(v) for v in s.split("x")) for s in args.strides.split(",")]
    print(f"map {args.size}×{args.size} cells, K=8, 4 vehicles, torch threads "
          f"{torch.get_num_threads()}; load average", open("/proc/loadavg").read().split()[:3])
    rows = []
    for width in ([None] if args.model else args.widths):
        model = make_model(width or 64, args.model)
        label = "checkpoint" if args.model else f"width {width}"

        def predictor(p, model=model):
            return predict(model, p, batch_size=2048)

        n_lit = args.literal_headings
        t0, c0 = time.perf_counter(), time.process_time()
        thetas = heading_bins(8)[:n_lit]
        ref_layers = []
        for theta in thetas:  # = directional_costmap_reference, one heading at a time
            ref_layers.append(_heading_layer(bev, float(theta), predictor, (1, 1), False, 2048))
        literal_s = (time.perf_counter() - t0) * 8 / n_lit
        literal_cpu = (time.process_time() - c0) * 8 / n_lit
        ref = 1 - np.clip(np.stack(ref_layers, 1), 0, 1)
        scaled = "" if n_lit == 8 else f" (measured on {n_lit} headings, ×{8 / n_lit:g})"
        rows.append((label, "literal stride 1", literal_s, literal_cpu, 1.0, 0.0, 0.0, scaled))

        fast = window_predictor(model, batch_size=2048)  # the pipeline's: channels-last
        runs = []
        for st in strides:
            runs += [(f"lattice {st[0]}×{st[1]}", st, predictor),
                     (f"lattice {st[0]}×{st[1]}, channels-last (the pipeline's)", st, fast)]
        plain_cpu = {}
        for proc, st, f in runs + [("dense", None, None)]:
            t0, c0 = time.perf_counter(), time.process_time()
            cost = (directional_costmap_dense(bev, model, 8, progress=False) if st is None
                    else directional_costmap(bev, f, 8, stride=st, progress=False))
            secs, cpu = time.perf_counter() - t0, time.process_time() - c0
            diff = np.abs(cost[:, :n_lit] - ref)
            note = ""
            if f is predictor:
                plain_cpu[st] = (cpu, cost)
            elif f is fast:  # against the same lattice in the default layout, this run
                base_cpu, base = plain_cpu[st]
                note = (f"; {base_cpu / cpu:.2f}× the lattice's CPU, max |ΔC| from it "
                        f"{np.abs(cost - base).max():.1e}")
            rows.append((label, proc, secs, cpu, literal_cpu / cpu, float(diff.mean()),
                         float(diff.max()), note))
    dgt_literal_cpu = rows[0][3]
    widths = args.pooled_widths or ([] if args.pooled else [32])
    pooled = ([(path, PooledNet.from_state_dict(torch.load(path, weights_only=True)))
               for path in args.pooled]
              + [("untrained", PooledNet(width=w).eval()) for w in widths])
    for name, net in pooled:
        label = f"PooledNet width {net.width}, depth {net.depth} ({name})"
        n_lit = args.literal_headings
        t0, c0 = time.perf_counter(), time.process_time()
        lit = [field_heading_layer(bev, float(theta), lambda r, on, net=net:
                                   net.literal_window_field(r.channels, r.observed, on))
               for theta in heading_bins(8)[:n_lit]]
        literal_s = (time.perf_counter() - t0) * 8 / n_lit
        literal_cpu = (time.process_time() - c0) * 8 / n_lit
        ref = 1 - np.clip(np.stack(lit, 1), 0, 1)
        ref[:, :, ~bev.observed] = 1.0
        scaled = "" if n_lit == 8 else f" (measured on {n_lit} headings, ×{8 / n_lit:g})"
        rows.append((label, "its literal, stride 1", literal_s, literal_cpu, 1.0, 0.0, 0.0,
                     scaled))
        runs = [("dense (exact)", net)] + ([("dense, bfloat16", bfloat16_copy(net))]
                                           if args.bf16 else [])
        for proc, model in runs:
            directional_costmap_dense(bev, model, 1, progress=False)  # warm-up
            t0, c0 = time.perf_counter(), time.process_time()
            cost = directional_costmap_dense(bev, model, 8, progress=False)
            secs, cpu = time.perf_counter() - t0, time.process_time() - c0
            diff = np.abs(cost[:, :n_lit] - ref)
            rows.append((label, proc, secs, cpu, literal_cpu / cpu, float(diff.mean()),
                         float(diff.max()), f"; {dgt_literal_cpu / cpu:.0f}× DGTNet's literal CPU"))
    print("\n| model | procedure | wall [s] | CPU [s] | speed-up (CPU) | mean abs diff "
          "| max abs diff |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for label, proc, secs, cpu, speedup, mad, maxd, note in rows:
        if 0 < maxd < 1e-3:  # float rounding only: show its size
            diffs = f"{mad:.1e} | {maxd:.1e}"
        else:
            diffs = f"{mad:.4f} | {maxd:.3f}"
        print(f"| {label} | {proc} | {secs:.1f}{note} | {cpu:.1f} | {speedup:.1f}× | {diffs} |")
    print("load average (1, 5, 15 min) at the end:", open("/proc/loadavg").read().split()[:3])


if __name__ == "__main__":
    main()
