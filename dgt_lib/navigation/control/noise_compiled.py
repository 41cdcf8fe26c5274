"""MPPI's noise drawn by numba: numpy's own stream, three times faster.

``np.random.default_rng(seed).standard_normal(out=a, dtype=np.float32)`` is a PCG64 bit
generator feeding numpy's float32 ziggurat, and it costs ~10 ns a number: half of an MPPI
call (2 × 56 × 1,000 normals) where every other step is compiled. :class:`NormalStream`
transcribes both — PCG64's 128-bit LCG step with its XSL-RR output, numpy's buffering of
32-bit halves, and ``random_standard_normal_f`` with its tables, float32 arithmetic and its
double-precision wedge test — so that it draws the same numbers to the bit from the same
seed, and the same stream across calls (``tests/test_noise_compiled.py`` compares them
over millions of draws, the ziggurat's rare tail and wedge branches included; checked on
x86-64 Linux with numpy 2.4). Both MPPI backends draw from it, so they agree whatever
numpy's C compiler made of the ziggurat on another platform. numba's own
``Generator.standard_normal`` is not numpy's stream: it tests the wedge in float32 and
left it after 13 million draws of seed 123.
"""

from __future__ import annotations

import numpy as np
from numba import njit, uint32, uint64
from numba.np.random import _constants as zig  # numpy's ziggurat tables, shipped by numba

KI, WI, FI = (np.asarray(zig.ki_float, np.uint32), np.asarray(zig.wi_float, np.float32),
              np.asarray(zig.fi_float, np.float32))
"""numpy's float32 ziggurat (its ziggurat_constants.h): each strip's acceptance bound on
the 23 random bits, its width, and the density at its edge."""
R, INV_R = np.float32(zig.ziggurat_nor_r_f), np.float32(zig.ziggurat_nor_inv_r_f)
MULT_HI, MULT_LO = uint64(0x2360ED051FC65DA4), uint64(0x4385DF649FCCF645)
"""PCG64's 128-bit multiplier, in halves."""
LOW32 = uint64(0xFFFFFFFF)


@njit(inline="always")
def _mul_high(a, b):
    """The high 64 bits of the 128-bit product of two uint64."""
    a0, a1, b0, b1 = a & LOW32, a >> uint64(32), b & LOW32, b >> uint64(32)
    lo_lo, lo_hi, hi_lo = a0 * b0, a0 * b1, a1 * b0
    mid = (lo_lo >> uint64(32)) + (lo_hi & LOW32) + (hi_lo & LOW32)
    return a1 * b1 + (lo_hi >> uint64(32)) + (hi_lo >> uint64(32)) + (mid >> uint64(32))


@njit(inline="always")
def _next64(s):
    """PCG64: state ← state · MULT + inc (mod 2¹²⁸), then XSL-RR of the new state.
    ``s`` = (state high, state low, inc high, inc low, has a buffered half, the half)."""
    lo = s[1] * MULT_LO
    hi = _mul_high(s[1], MULT_LO) + s[0] * MULT_LO + s[1] * MULT_HI
    new_lo = lo + s[3]
    hi += s[2] + (uint64(1) if new_lo < lo else uint64(0))
    s[0], s[1] = hi, new_lo
    x, rot = hi ^ new_lo, hi >> uint64(58)
    return (x >> rot) | (x << ((uint64(64) - rot) & uint64(63)))


@njit(inline="always")
def _next32(s):
    """numpy's 32-bit draw: the low half of a 64-bit output, the high half kept for next."""
    if s[4]:
        s[4] = uint64(0)
        return uint32(s[5])
    out = _next64(s)
    s[4], s[5] = uint64(1), out >> uint64(32)
    return uint32(out & LOW32)


@njit(inline="always")
def _next_float(s):
    """A uniform float32 in [0, 1) from 24 bits of a 32-bit draw."""
    return np.float32(_next32(s) >> uint32(8)) * np.float32(1.0 / 16777216.0)


@njit(inline="always")
def _normal(s):
    """numpy's ``random_standard_normal_f``: one standard normal float32."""
    while True:
        r = _next32(s)
        idx = r & uint32(0xFF)
        rabs = (r >> uint32(9)) & uint32(0x7FFFFF)
        x = np.float32(np.float32(rabs) * WI[idx])
        x = -x if (r >> uint32(8)) & uint32(1) else x  # the sign bit
        if rabs < KI[idx]:  # ~99 % of draws
            return x
        if idx == 0:  # the tail beyond R
            while True:
                xx = np.float32(-INV_R * np.float32(np.log1p(-_next_float(s))))
                yy = np.float32(-np.float32(np.log1p(-_next_float(s))))
                if np.float32(yy + yy) > np.float32(xx * xx):
                    tail = np.float32(R + xx)
                    return -tail if (rabs >> uint32(8)) & uint32(1) else tail
        else:  # the wedge: float32 on the left, double on the right, as numpy's C
            u = np.float32(np.float32(FI[idx - 1] - FI[idx]) * _next_float(s))
            if np.float64(np.float32(u + FI[idx])) < np.exp(-0.5 * np.float64(x) * np.float64(x)):
                return x


@njit(cache=True)
def _fill(s, flat):
    """Standard normals into every element of the 1-D float32 array ``flat``."""
    for i in range(flat.size):
        flat[i] = _normal(s)


class NormalStream:
    """``np.random.default_rng(seed)``'s float32 standard normals, drawn by numba: the
    drop-in for :func:`~dgt_lib.navigation.control.sampling.draw_noise`'s generator."""

    def __init__(self, seed: int | None) -> None:
        state = np.random.default_rng(seed).bit_generator.state
        pcg, mask = state["state"], (1 << 64) - 1
        self.state = np.array([pcg["state"] >> 64, pcg["state"] & mask, pcg["inc"] >> 64,
                               pcg["inc"] & mask, state["has_uint32"], state["uinteger"]],
                              dtype=np.uint64)

    def standard_normal(self, *, out: np.ndarray, dtype=np.float32) -> np.ndarray:
        """Fill the C-contiguous float32 array ``out`` as numpy's Generator would."""
        if dtype is not np.float32 or out.dtype != np.float32 or not out.flags.c_contiguous:
            raise ValueError("NormalStream draws into C-contiguous float32 arrays only")
        _fill(self.state, out.reshape(-1))
        return out
