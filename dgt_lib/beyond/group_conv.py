"""The C8 group convolution of :class:`~dgt_lib.beyond.equivariant.C8Net`: the group action
on filters and the three layers built from it.

How it is built (our own small group convolution, no dependency): a *rotated filter
bank*. A lifting layer correlates the scalar input channels (R, G, B, σ_H, ‖∇H̄‖:
unchanged by a rotation) with 8 rotated copies ψ_r = L_{g^r} ψ of each learned filter
ψ; a group layer's filter ψ(q, s) also carries a heading index s,
and its copies are ψ_r(q, s) = ψ(g^−r q, s − r) (rotate, then shift the heading axis
cyclically). Spatial rotation by a multiple of 90° is an exact permutation of the k × k
filter's cells (:func:`rot90_world`); by 45° it is a fixed bilinear resampling matrix
(:func:`rotation_matrix_45`), and ψ_{2m+1} = rot90^m(R₄₅ ψ). So 90° rotations of the map
permute the output exactly (up to float rounding), 45° rotations only approximately:
the map itself cannot be rotated by 45° on a square grid without interpolation either.
Filters are masked to a disk. ReLU is pointwise and BatchNorm shares its statistics
over the 8 headings of a field, so both commute with the group action.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

N_ROTATIONS = 8
"""|C8|: the K = 8 heading bins of the paper, 45° apart."""


def rot90_world(x: torch.Tensor, times: int = 1) -> torch.Tensor:
    """Rotate the last two axes (row = y, column = x, as on a :class:`GridSpec`) by
    ``times`` × 90° counter-clockwise in the world frame (+x → +y): exact, a permutation.

    out[r, c] = x[−c, r] in centred indices, i.e. (L_g x)(p) = x(g⁻¹ p)."""
    return torch.rot90(x, times, dims=(-1, -2))


def rotation_matrix_45(size: int) -> torch.Tensor:
    """(size², size²) bilinear resampling that rotates a size × size filter by +45°
    (world frame, counter-clockwise): ψ′(p) = ψ(R(−45°) p), p in cell offsets from the
    centre (column = x, row = y). Samples outside the filter read 0."""
    c = (size - 1) / 2.0
    m = np.zeros((size * size, size * size))
    cos, sin = math.cos(math.pi / 4), math.sin(math.pi / 4)
    for r in range(size):
        for col in range(size):
            x, y = col - c, r - c
            sx, sy = cos * x + sin * y, -sin * x + cos * y  # R(−45°) p
            fc, fr = sx + c, sy + c
            c0, r0 = math.floor(fc), math.floor(fr)
            for dr in (0, 1):
                for dc in (0, 1):
                    rr, cc = r0 + dr, c0 + dc
                    w = (1 - abs(fr - rr)) * (1 - abs(fc - cc))
                    if w > 0 and 0 <= rr < size and 0 <= cc < size:
                        m[r * size + col, rr * size + cc] += w
    return torch.tensor(m, dtype=torch.float32)


def disk_mask(size: int) -> torch.Tensor:
    """(size, size) 1 on the cells within (size − 1)/2 + 0.5 of the centre, else 0."""
    c = (size - 1) / 2.0
    r, col = np.mgrid[0:size, 0:size]
    return torch.tensor(np.hypot(r - c, col - c) <= c + 0.5, dtype=torch.float32)


def rotated_filter_bank(weight: torch.Tensor, r45: torch.Tensor) -> torch.Tensor:
    """The 8 rotated copies of filters (..., k, k): (8, ..., k, k), copy r = L_{g^r} ψ
    (90° multiples exact; odd r = rot90^m(R₄₅ ψ))."""
    k = weight.shape[-1]
    turned = (weight.reshape(-1, k * k) @ r45.T).reshape(weight.shape)
    return torch.stack([rot90_world(turned if r % 2 else weight, r // 2)
                        for r in range(N_ROTATIONS)])


class LiftingConv(nn.Module):
    """Scalar channels (B, C_in, H, W) → regular fields (B, C_out·8, H − k + 1, W − k + 1);
    output channel o·8 + r is the correlation with L_{g^r} ψ_o ("valid", no padding)."""

    def __init__(self, in_channels: int, fields: int, size: int) -> None:
        super().__init__()
        self.weight = nn.Parameter(torch.empty(fields, in_channels, size, size))
        nn.init.kaiming_normal_(self.weight, nonlinearity="relu")
        self.register_buffer("mask", disk_mask(size))
        self.register_buffer("r45", rotation_matrix_45(size))

    def full_weight(self) -> torch.Tensor:
        bank = rotated_filter_bank(self.weight * self.mask, self.r45)  # (8, O, I, k, k)
        return bank.transpose(0, 1).flatten(0, 1)  # (O·8, I, k, k)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.conv2d(x, self.full_weight())


class GroupConv(nn.Module):
    """Regular fields (B, C_in·8, H, W) → (B, C_out·8, H − k + 1, W − k + 1) with filters
    ψ(q, s), copies ψ_r(q, s) = ψ(g^−r q, s − r); ``bias`` (per field) for the last layer."""

    def __init__(self, in_fields: int, out_fields: int, size: int, bias: bool = False) -> None:
        super().__init__()
        self.weight = nn.Parameter(torch.empty(out_fields, in_fields, N_ROTATIONS, size, size))
        nn.init.kaiming_normal_(self.weight.view(out_fields, -1, size, size),
                                nonlinearity="relu")
        self.bias = nn.Parameter(torch.zeros(out_fields)) if bias else None
        self.register_buffer("mask", disk_mask(size))
        self.register_buffer("r45", rotation_matrix_45(size))

    def full_weight(self) -> torch.Tensor:
        w = self.weight * self.mask
        bank = rotated_filter_bank(w, self.r45)  # (8, O, I, 8, k, k), spatially rotated
        bank = torch.stack([torch.roll(bank[r], r, dims=2) for r in range(N_ROTATIONS)])
        return bank.transpose(0, 1).flatten(0, 1).flatten(1, 2)  # (O·8, I·8, k, k)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        bias = None if self.bias is None else self.bias.repeat_interleave(N_ROTATIONS)
        return F.conv2d(x, self.full_weight(), bias)


class GroupBatchNorm(nn.Module):
    """BatchNorm of regular fields: statistics and affine shared by a field's 8 channels."""

    def __init__(self, fields: int) -> None:
        super().__init__()
        self.bn = nn.BatchNorm2d(fields)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, c, h, w = x.shape
        return self.bn(x.reshape(b, c // N_ROTATIONS, N_ROTATIONS * h, w)).reshape(b, c, h, w)
