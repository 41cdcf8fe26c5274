"""Adam's three CPU implementations on DGTNet: time of the optimiser step, and whether each
gives the default's weights to the bit.

    .venv/bin/python benchmarks/bench_adam.py --width 64 --steps 4

Trains a fresh DGTNet (same seed) for ``--steps`` steps on fixed random batches of 256
patches with ``torch.optim.Adam`` as the pipeline builds it (the for-loop implementation),
with ``fused=True`` and with ``foreach=True``, and prints each one's total and optimiser
seconds and the largest weight difference from the default.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import torch

from dgt_lib.core.config import VEHICLES
from dgt_lib.learning.model import DGTNet


def run(batches: torch.Tensor, targets: torch.Tensor, width: int, **adam) -> tuple:
    """(state dict, total seconds, optimiser seconds) of training with ``Adam(**adam)``."""
    torch.manual_seed(0)
    model = DGTNet(tuple(VEHICLES), width=width).train()
    opt = torch.optim.Adam(model.parameters(), lr=1e-3, **adam)
    t_opt, t0 = 0.0, time.perf_counter()
    for x, y in zip(batches, targets, strict=True):
        loss = ((model(x) - y) ** 2).mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        t = time.perf_counter()
        opt.step()
        t_opt += time.perf_counter() - t
    return model.state_dict(), time.perf_counter() - t0, t_opt


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=64)
    parser.add_argument("--steps", type=int, default=4)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    x = torch.from_numpy(rng.standard_normal((args.steps, 256, 6, 22, 7)).astype(np.float32))
    y = torch.from_numpy(rng.random((args.steps, 256, len(VEHICLES))).astype(np.float32))
    print(f"width {args.width}, {args.steps} steps of 256 patches; torch {torch.__version__}, "
          f"{torch.get_num_threads()} threads, load average {os.getloadavg()[0]:.2f}\n")
    print("| Adam | total [s] | optimiser [s] | max |Δw| from the default |")
    print("| --- | --- | --- | --- |")
    reference = None
    for name, kw in (("default (for-loop)", {}), ("fused", {"fused": True}),
                     ("foreach", {"foreach": True})):
        state, total, t_opt = run(x, y, args.width, **kw)
        reference = reference or state
        diff = max(float((state[k].double() - reference[k].double()).abs().max())
                   for k in state)
        print(f"| {name} | {total:.2f} | {t_opt:.2f} | {diff:.1e} |", flush=True)


if __name__ == "__main__":
    main()
