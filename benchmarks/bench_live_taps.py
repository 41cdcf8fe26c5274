"""How much of DGTNet's training multiplies zero padding: a probe for issue 17's training.

On a 22 × 7 patch ResNet-18's maps shrink to 6×2, 3×1, 2×1 and 1×1, so most taps of its
3×3 convolutions fall on the zero padding: on layer4's 1×1 maps only the centre tap
meets data. This script times a training step (forward, backward, Adam) of DGTNet as it
is and of the same network whose convolutions use only their *live* taps — the kernel
cropped to the taps that ever meet the input, the padding shifted to match — which is
the same function (the output differs only by float rounding; printed).

Not used by the pipeline: the cropped convolution sums in another order, so models would
train to different last bits and every recorded result would have to be rerun.

Run: ``.venv/bin/python benchmarks/bench_live_taps.py [--steps 12]`` on idle cores.
"""

from __future__ import annotations

import argparse
import os
import time

import torch
import torch.nn as nn
import torch.nn.functional as F

from dgt_lib.learning.model import PATCH_SHAPE, DGTNet


def live_taps(n: int, k: int, p: int, s: int) -> tuple[int, int, int, int]:
    """For a convolution of kernel ``k``, padding ``p``, stride ``s`` along an input of
    ``n`` pixels: the live taps [i0, i1) (those that meet the input for some output) and
    the (before, after) padding that keeps the output's size with only them."""
    out = (n + 2 * p - k) // s + 1
    live = [i for i in range(k) if any(0 <= o * s - p + i < n for o in range(out))]
    i0, i1 = live[0], live[-1] + 1
    before = p - i0
    return i0, i1, before, (out - 1) * s + (i1 - i0) - n - before


class LiveTapsConv(nn.Module):
    """``conv`` evaluated with its live taps only (same weights, same function)."""

    def __init__(self, conv: nn.Conv2d):
        super().__init__()
        self.conv = conv

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        c = self.conv
        h0, h1, top, bottom = live_taps(x.shape[-2], c.kernel_size[0], c.padding[0], c.stride[0])
        w0, w1, left, right = live_taps(x.shape[-1], c.kernel_size[1], c.padding[1], c.stride[1])
        weight = c.weight[:, :, h0:h1, w0:w1]
        if top == bottom and left == right:
            return F.conv2d(x, weight, None, c.stride, (top, left))
        return F.conv2d(F.pad(x, (left, right, top, bottom)), weight, None, c.stride)


def with_live_taps(model: nn.Module) -> nn.Module:
    """Wrap every convolution larger than 1 × 1 of ``model`` in :class:`LiveTapsConv`."""
    for module in list(model.modules()):
        for name, child in list(module.named_children()):
            if isinstance(child, nn.Conv2d) and child.kernel_size != (1, 1):
                setattr(module, name, LiveTapsConv(child))
    return model


def step_seconds(model: nn.Module, x: torch.Tensor, y: torch.Tensor, steps: int) -> float:
    """Median seconds of a training step after one warm-up step."""
    opt = torch.optim.Adam(model.parameters(), 1e-3)
    times = []
    for _ in range(steps + 1):
        t0 = time.perf_counter()
        opt.zero_grad()
        F.mse_loss(model(x), y).backward()
        opt.step()
        times.append(time.perf_counter() - t0)
    return float(torch.tensor(times[1:]).median())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=12)
    args = ap.parse_args()
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, "
          f"load average {os.getloadavg()[0]:.1f}")
    for width, batch in ((32, 128), (64, 256)):  # demo's and paper's network and batch
        torch.manual_seed(0)
        x, y = torch.rand(batch, *PATCH_SHAPE), torch.rand(batch, 4)
        standard = DGTNet(width=width)
        live = DGTNet(width=width)
        live.load_state_dict(standard.state_dict())
        with_live_taps(live)
        with torch.no_grad():
            diff = (standard.eval()(x) - live.eval()(x)).abs().max().item()
        t_std = step_seconds(standard.train(), x, y, args.steps)
        t_live = step_seconds(live.train(), x, y, args.steps)
        print(f"width {width}, batch {batch}: training step {1e3 * t_std:.0f} ms as is, "
              f"{1e3 * t_live:.0f} ms with live taps only ({t_std / t_live:.2f}×); "
              f"max |Δ output| {diff:.1e}")


if __name__ == "__main__":
    main()
