"""Adam's CPU implementations on DGTNet: time of the optimiser step, and whether each
gives the default's weights to the bit.

    .venv/bin/python benchmarks/bench_adam.py --width 64 --steps 8

Trains a fresh DGTNet (same seed) for ``--steps`` steps on fixed random batches of 256
patches with ``torch.optim.Adam`` as the pipeline builds it (the for-loop implementation),
with ``fused=True``, with ``foreach=True`` and with :class:`CompiledAdam` (below), and
prints each one's total and optimiser seconds (median step after the first two) and the
largest weight difference from the default.

:class:`CompiledAdam` is a candidate that was measured and not adopted (docs/
platform-facts.md → torch on the CPU): the for-loop's float32 arithmetic in two numba
passes around torch's own square root, bit for bit the default's weights —

    m ← fma(1 − β₁, g − m, m)            exp_avg.lerp_(g, 1 − β₁) (torch's kernel: an FMA)
    v ← fma((1 − β₂)·g, g, β₂·v)         exp_avg_sq.mul_(β₂).addcmul_(g, g, 1 − β₂)
    s ← √v                               torch (its vectorised float32 sqrt is not
                                         correctly rounded: 1 ulp off on ~20 % of values)
    θ ← θ + (−lr/(1 − β₁ᵗ))·m / (s/√(1 − β₂ᵗ) + ε)

— and ``--isolated`` times its step alone on random gradients, where it is faster than the
for-loop; inside a training loop it was not (numba's OpenMP threads and torch's contend for
the cores).
"""

from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np
import torch
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from dgt_lib.core.config import VEHICLES
from dgt_lib.learning.model import DGTNet


@intrinsic
def _fma(typingctx, a, b, c):
    """a·b + c rounded once (float32), as torch's vectorised lerp computes it."""
    sig = types.float32(types.float32, types.float32, types.float32)

    def codegen(context, builder, signature, args):
        f32 = ir.FloatType()
        fn = builder.module.declare_intrinsic("llvm.fma", [f32],
                                              ir.FunctionType(f32, [f32, f32, f32]))
        return builder.call(fn, args)

    return sig, codegen


@numba.njit(parallel=True)
def _moments(grad, exp_avg, exp_avg_sq, one_minus_beta1, beta2, one_minus_beta2):
    for i in numba.prange(grad.size):
        g = grad[i]
        exp_avg[i] = _fma(one_minus_beta1, g - exp_avg[i], exp_avg[i])
        exp_avg_sq[i] = _fma(one_minus_beta2 * g, g, exp_avg_sq[i] * beta2)


@numba.njit(parallel=True)
def _update(param, exp_avg, sqrt_v, bias_correction2_sqrt, eps, neg_step_size):
    for i in numba.prange(param.size):
        denom = sqrt_v[i] / bias_correction2_sqrt + eps
        param[i] = param[i] + neg_step_size * exp_avg[i] / denom


def _flat(t: torch.Tensor) -> np.ndarray:
    return t.detach().view(-1).numpy()


class CompiledAdam(torch.optim.Adam):
    """``torch.optim.Adam`` (no weight decay, AMSGrad or maximize; float32 CPU weights)
    whose step is two compiled passes around torch's √v (module doc)."""

    @torch.no_grad()
    def step(self, closure=None):
        numba.set_num_threads(min(torch.get_num_threads(), numba.config.NUMBA_NUM_THREADS))
        f32 = np.float32
        for group in self.param_groups:
            assert group["weight_decay"] == 0 and not group["amsgrad"] and not group["maximize"]
            beta1, beta2 = group["betas"]
            for p in group["params"]:
                if p.grad is None:
                    continue
                state = self.state[p]
                if not state:  # as torch.optim.Adam initialises it
                    state["step"] = torch.tensor(0.0, dtype=torch.float32)
                    state["exp_avg"] = torch.zeros_like(p, memory_format=torch.preserve_format)
                    state["exp_avg_sq"] = torch.zeros_like(p, memory_format=torch.preserve_format)
                state["step"] += 1
                step = state["step"].item()
                exp_avg, exp_avg_sq = _flat(state["exp_avg"]), _flat(state["exp_avg_sq"])
                _moments(_flat(p.grad), exp_avg, exp_avg_sq, f32(1 - beta1), f32(beta2),
                         f32(1 - beta2))
                sqrt_v = self._scratch(p.numel())
                torch.sqrt(state["exp_avg_sq"].view(-1), out=sqrt_v)  # torch's rounding
                _update(_flat(p), exp_avg, sqrt_v.numpy(), f32((1 - beta2**step) ** 0.5),
                        f32(group["eps"]), f32(-(group["lr"] / (1 - beta1**step))))

    def _scratch(self, n: int) -> torch.Tensor:
        """A reused float32 buffer for √v (a fresh one each step costs page faults)."""
        buf = getattr(self, "_sqrt_buffer", None)
        if buf is None or buf.numel() < n:
            buf = self._sqrt_buffer = torch.empty(n, dtype=torch.float32)
        return buf[:n]


def run(batches: torch.Tensor, targets: torch.Tensor, width: int, cls=torch.optim.Adam,
        **adam) -> tuple:
    """(state dict, median step seconds, median optimiser seconds) of training with
    ``cls(**adam)``; the first two steps (compilation, state allocation) not counted."""
    torch.manual_seed(0)
    model = DGTNet(tuple(VEHICLES), width=width).train()
    opt = cls(model.parameters(), lr=1e-3, **adam)
    t_step, t_opt = [], []
    for x, y in zip(batches, targets, strict=True):
        t0 = time.perf_counter()
        loss = ((model(x) - y) ** 2).mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        t = time.perf_counter()
        opt.step()
        t_opt.append(time.perf_counter() - t)
        t_step.append(time.perf_counter() - t0)
    return model.state_dict(), np.median(t_step[2:]), np.median(t_opt[2:])


def isolated(width: int, steps: int) -> None:
    """The optimiser step alone, on random gradients (no forward or backward between)."""
    params = list(DGTNet(tuple(VEHICLES), width=width).parameters())
    print(f"\nthe step alone ({sum(p.numel() for p in params):,} weights, median of {steps}):")
    for name, cls in (("default (for-loop)", torch.optim.Adam), ("compiled", CompiledAdam)):
        opt = cls(params, lr=1e-3)
        for p in params:
            p.grad = torch.randn_like(p) * 1e-3
        times = []
        for _ in range(steps + 2):
            t = time.perf_counter()
            opt.step()
            times.append(time.perf_counter() - t)
        print(f"  {name:20s} {1e3 * np.median(times[2:]):6.1f} ms")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=64)
    parser.add_argument("--steps", type=int, default=8)
    parser.add_argument("--isolated", action="store_true",
                        help="also time the step alone, without a training loop around it")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    x = torch.from_numpy(rng.standard_normal((args.steps, 256, 6, 22, 7)).astype(np.float32))
    y = torch.from_numpy(rng.random((args.steps, 256, len(VEHICLES))).astype(np.float32))
    print(f"width {args.width}, {args.steps} steps of 256 patches; torch {torch.__version__}, "
          f"{torch.get_num_threads()} threads, load average {os.getloadavg()[0]:.2f}\n")
    print("| Adam | training step [ms] | optimiser step [ms] | max \\|Δw\\| from the default |")
    print("| --- | --- | --- | --- |")
    reference = None
    for name, cls, kw in (("default (for-loop)", torch.optim.Adam, {}),
                          ("fused", torch.optim.Adam, {"fused": True}),
                          ("foreach", torch.optim.Adam, {"foreach": True}),
                          ("compiled (2 numba passes)", CompiledAdam, {})):
        state, t_step, t_opt = run(x, y, args.width, cls, **kw)
        reference = reference or state
        diff = max(float((state[k].double() - reference[k].double()).abs().max())
                   for k in state)
        print(f"| {name} | {1e3 * t_step:.0f} | {1e3 * t_opt:.1f} | {diff:.1e} |", flush=True)
    if args.isolated:
        isolated(args.width, args.steps)


if __name__ == "__main__":
    main()
