"""The dual-branch multi-task traversability network (paper: Network Architecture).

A patch P of shape ``(6, 22, 7)`` (channels R, G, B, H̄, σ_H, ‖∇H̄‖; forward =
row 0) is normalised per channel, split into its RGB and height channels, and
each group goes through its own ResNet-18: the RGB branch may start from
torchvision's ImageNet weights, the height branch always starts from scratch.
The two embeddings are concatenated, passed through a small fully connected
network, and one regression head per vehicle predicts the locomotion
L̂_v(P) ∈ [0, 1]::

    x (B, 6, 22, 7) ─ normalise ─┬─ RGB (B, 3, 22, 7) ── ResNet-18 ── (B, 8·width) ─┐
                                 └─ H   (B, 3, 22, 7) ── ResNet-18 ── (B, 8·width) ─┴─ concat
       (B, 16·width) ── FC + ReLU ── z (B, fc_hidden) ── head_v ── sigmoid ── L̂ (B, n_vehicles)

:meth:`DGTNet.embed` computes z once and :meth:`DGTNet.heads` evaluates every
vehicle's head from it, so a costmap pays for the backbone once per patch, not
once per vehicle.

The ResNet is written out here (no torchvision) with torchvision's parameter
names (``conv1``, ``bn1``, ``layer1.0.conv1``, ``layer2.0.downsample.0`` …), so
``DGTNet(rgb_weights="resnet18-f37072fd.pth")`` loads torchvision's ImageNet
state dict into the RGB branch. ``width`` scales every layer (64 = the standard
ResNet-18 of the paper; smaller widths trade accuracy for speed, see
``benchmarks/bench_train.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from dgt_lib.core.config import VEHICLES

N_CHANNELS = 6
"""Patch channels R, G, B, H̄, σ_H, ‖∇H̄‖ (docs/ARCHITECTURE.md → Conventions)."""
RGB_CHANNELS = slice(0, 3)
HEIGHT_CHANNELS = slice(3, 6)
INPUT_CHANNELS: dict[str, tuple[int, ...]] = {"rgbd": (0, 1, 2, 3, 4, 5),
                                              "geometry": (3, 4, 5), "rgb": (0, 1, 2)}
"""The channels each ``TrainConfig.inputs`` choice lets the network see; the others enter
as their training mean (the input attribution study)."""
PATCH_SHAPE = (N_CHANNELS, 22, 7)
"""One patch: 8.8 m × 2.8 m at 0.4 m per cell, channels first."""
HEAD_PRIOR_CLIP = (0.01, 0.99)
""":meth:`DGTNet.init_heads` clips each mean label into this range (|bias| ≤ logit(0.99) ≈ 4.6)."""


def centre_heights(x):
    """Make H̄ relative to each patch's mean height: (B, 6, H, W) → a copy, numpy or torch.

    Traversability does not depend on altitude, and absolute heights differ between
    the training map and the evaluation maps (a summit at 12 m is as flat as a valley),
    so the network sees H̄ − mean(H̄) of its patch. Our choice; the paper does not say.
    Non-finite cells are ignored in the mean and stay non-finite.
    """
    if isinstance(x, torch.Tensor):
        out = x.clone()
        mean = torch.nanmean(x[:, HEIGHT_CHANNELS.start].flatten(1), dim=1)
        out[:, HEIGHT_CHANNELS.start] -= torch.nan_to_num(mean)[:, None, None]
        return out
    out = np.array(x, dtype=np.float64 if x.dtype == np.float64 else np.float32)
    h = out[:, HEIGHT_CHANNELS.start].reshape(len(out), -1)
    finite = np.isfinite(h)
    mean = np.where(finite, h, 0.0).sum(axis=1) / np.maximum(finite.sum(axis=1), 1)
    out[:, HEIGHT_CHANNELS.start] -= mean[:, None, None]
    return out


def head_column(heads: Sequence[str], vehicle: str | int) -> int:
    """Column of ``vehicle`` (name, or index into ``config.VEHICLES``) among a model's
    ``heads`` (vehicle names in output order); KeyError naming the heads if it has none."""
    name = VEHICLES[vehicle] if isinstance(vehicle, (int, np.integer)) else vehicle
    if name not in heads:
        raise KeyError(f"this model has no head for {name!r}; its heads: {tuple(heads)}")
    return list(heads).index(name)


class ArchitectureMismatchError(ValueError):
    """Weights or a checkpoint that do not fit the network they are loaded into."""


@lru_cache(maxsize=256)
def live_taps(n: int, k: int, p: int, s: int) -> tuple[int, int, int, int]:
    """Along one axis of a convolution (input ``n`` pixels, kernel ``k``, zero padding
    ``p``, stride ``s``): the taps [i0, i1) that meet the input for some output, and the
    padding (before, after) that keeps the output's size with only those taps."""
    out = (n + 2 * p - k) // s + 1
    live = [i for i in range(k) if any(0 <= o * s - p + i < n for o in range(out))]
    i0, i1 = live[0], live[-1] + 1
    before = p - i0
    return i0, i1, before, (out - 1) * s + (i1 - i0) - n - before


class PatchConv2d(nn.Conv2d):
    """``nn.Conv2d`` (same parameters and state dict) that can skip its dead taps.

    On a 22 × 7 patch ResNet-18's maps shrink to 6×2, 3×1, 2×1 and 1×1, where most taps
    of a 3×3 kernel only ever meet the zero padding (on 1×1 maps all but the centre).
    With ``live_taps`` True the kernel is cropped to the taps that meet the input and the
    padding shifted to match: the same function with fewer multiplications, summed in
    another order (not bit-identical). Off by default; docs/training.md.
    """

    live_taps: bool = False

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.live_taps or self.groups != 1 or self.bias is not None:
            return super().forward(x)
        (kh, kw), (ph, pw), (sh, sw) = self.kernel_size, self.padding, self.stride
        h0, h1, top, bottom = live_taps(x.shape[-2], kh, ph, sh)
        w0, w1, left, right = live_taps(x.shape[-1], kw, pw, sw)
        if (h1 - h0, w1 - w0) == (kh, kw):
            return super().forward(x)
        weight = self.weight[:, :, h0:h1, w0:w1]
        if top == bottom and left == right:
            return F.conv2d(x, weight, None, self.stride, (top, left), self.dilation)
        return F.conv2d(F.pad(x, (left, right, top, bottom)), weight, None, self.stride, 0,
                        self.dilation)


class BasicBlock(nn.Module):
    """torchvision's ResNet ``BasicBlock``: two 3×3 convolutions and a skip connection."""

    expansion = 1

    def __init__(self, inplanes: int, planes: int, stride: int = 1,
                 downsample: nn.Module | None = None) -> None:
        super().__init__()
        self.conv1 = PatchConv2d(inplanes, planes, 3, stride=stride, padding=1, bias=False)
        self.bn1 = nn.BatchNorm2d(planes)
        self.relu = nn.ReLU(inplace=True)
        self.conv2 = PatchConv2d(planes, planes, 3, stride=1, padding=1, bias=False)
        self.bn2 = nn.BatchNorm2d(planes)
        self.downsample = downsample

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        identity = x if self.downsample is None else self.downsample(x)
        out = self.relu(self.bn1(self.conv1(x)))
        out = self.bn2(self.conv2(out))
        return self.relu(out + identity)


class ResNet18(nn.Module):
    """ResNet-18 without its classifier: (B, in_channels, H, W) → (B, 8·width) embedding.

    The standard ImageNet stem (7×7 convolution, stride 2, then 3×3 max-pool,
    stride 2) and four stages of two ``BasicBlock`` each. On a 22 × 7 patch the
    feature map shrinks 22×7 → 11×4 → 6×2 (layer1) → 3×1 → 2×1 → 1×1 (layer4).
    Parameter names match torchvision's ``resnet18`` minus ``fc``.
    """

    def __init__(self, in_channels: int = 3, width: int = 64) -> None:
        super().__init__()
        if width < 1:
            raise ValueError(f"width must be a positive integer, got {width}")
        self.inplanes = width
        self.conv1 = PatchConv2d(in_channels, width, kernel_size=7, stride=2, padding=3,
                                 bias=False)
        self.bn1 = nn.BatchNorm2d(width)
        self.relu = nn.ReLU(inplace=True)
        self.maxpool = nn.MaxPool2d(kernel_size=3, stride=2, padding=1)
        self.layer1 = self._make_layer(width, 2)
        self.layer2 = self._make_layer(2 * width, 2, stride=2)
        self.layer3 = self._make_layer(4 * width, 2, stride=2)
        self.layer4 = self._make_layer(8 * width, 2, stride=2)
        self.avgpool = nn.AdaptiveAvgPool2d((1, 1))
        self.out_features = 8 * width
        for m in self.modules():  # torchvision's initialisation
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
            elif isinstance(m, nn.BatchNorm2d):
                nn.init.constant_(m.weight, 1)
                nn.init.constant_(m.bias, 0)

    def _make_layer(self, planes: int, blocks: int, stride: int = 1) -> nn.Sequential:
        downsample = None
        if stride != 1 or self.inplanes != planes:
            downsample = nn.Sequential(
                nn.Conv2d(self.inplanes, planes, 1, stride=stride, bias=False),
                nn.BatchNorm2d(planes),
            )
        layers = [BasicBlock(self.inplanes, planes, stride, downsample)]
        self.inplanes = planes
        layers += [BasicBlock(planes, planes) for _ in range(1, blocks)]
        return nn.Sequential(*layers)

    def feature_map(self, x: torch.Tensor) -> torch.Tensor:
        """Layer-4 features before pooling: (B, C, H, W) → (B, 8·width, ⌈H/32⌉, ⌈W/32⌉)."""
        x = self.maxpool(self.relu(self.bn1(self.conv1(x))))
        return self.layer4(self.layer3(self.layer2(self.layer1(x))))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.flatten(self.avgpool(self.feature_map(x)), 1)  # (B, 8·width)


def load_torchvision_weights(branch: ResNet18, path: str | Path) -> None:
    """Load a torchvision ``resnet18`` state dict file into ``branch`` (its ``fc.*`` is ignored).

    Raises :class:`ArchitectureMismatchError` naming the missing, unexpected or
    wrongly shaped keys when the file is not a ResNet-18 of the branch's width.
    """
    state = torch.load(Path(path), map_location="cpu", weights_only=True)
    if isinstance(state, dict) and "state_dict" in state:
        state = state["state_dict"]
    if not isinstance(state, dict):
        raise ArchitectureMismatchError(
            f"{path}: expected a state dict, got {type(state).__name__}")
    state = {k: v for k, v in state.items() if not k.startswith("fc.")}
    own = branch.state_dict()
    missing = sorted(set(own) - set(state))
    unexpected = sorted(set(state) - set(own))
    wrong = sorted(k for k in set(own) & set(state) if own[k].shape != state[k].shape)
    if missing or unexpected or wrong:
        parts = [f"{name}: {keys[:4]}{' …' if len(keys) > 4 else ''}"
                 for name, keys in (("missing", missing), ("unexpected", unexpected),
                                    ("wrong shape", wrong)) if keys]
        raise ArchitectureMismatchError(
            f"{path} is not a torchvision ResNet-18 state dict for an RGB branch of width "
            f"{branch.conv1.out_channels} ({'; '.join(parts)})")
    branch.load_state_dict(state)


class DGTNet(nn.Module):
    """Dual-branch ResNet-18, shared FC trunk, one sigmoid regression head per vehicle.

    Args:
        vehicles: names of the vehicles, one head each, in head order (default all
            four of ``config.VEHICLES``; a single-task model has one).
        width: channels of the first ResNet stage (64 = ResNet-18 as in the paper).
        fc_hidden: units of the fully connected layer after the concatenation.
        rgb_weights: optional path to torchvision's ImageNet ``resnet18`` state dict
            (e.g. ``resnet18-f37072fd.pth``); needs ``width=64``. Without it the
            RGB branch starts from random weights and ``rgb_pretrained`` is False.

    Input: patches (B, 6, 22, 7) float32 in raw units (RGB 0..1, heights in
    metres); the per-channel normalisation (buffers ``input_mean``/``input_std``,
    set with :meth:`set_normalization` from the training split and saved in the
    state dict) is applied inside :meth:`embed`, so inference cannot forget it.
    Non-finite inputs (NaN in unobserved cells) become the channel mean.
    Output: (B, len(vehicles)) float32 in [0, 1], column j = vehicle ``vehicles[j]``.
    """

    def __init__(self, vehicles: tuple[str, ...] | list[str] = VEHICLES, width: int = 64,
                 fc_hidden: int = 256, rgb_weights: str | Path | None = None,
                 inputs: str = "rgbd") -> None:
        super().__init__()
        vehicles = tuple(vehicles)
        unknown = [v for v in vehicles if v not in VEHICLES]
        if not vehicles or unknown or len(set(vehicles)) != len(vehicles):
            raise ValueError(f"vehicles must be distinct names from {VEHICLES}, got {vehicles}")
        if inputs not in INPUT_CHANNELS:
            raise ValueError(f"inputs must be one of {', '.join(INPUT_CHANNELS)}, got {inputs!r}")
        self.vehicles = vehicles
        self.inputs = inputs
        self.width = int(width)
        self.fc_hidden = int(fc_hidden)
        self.rgb = ResNet18(3, self.width)
        self.height = ResNet18(3, self.width)
        self.fc = nn.Sequential(
            nn.Linear(self.rgb.out_features + self.height.out_features, self.fc_hidden),
            nn.ReLU(inplace=True),
        )
        self.vehicle_heads = nn.ModuleList(nn.Linear(self.fc_hidden, 1) for _ in vehicles)
        self.register_buffer("input_mean", torch.zeros(N_CHANNELS))
        self.register_buffer("input_std", torch.ones(N_CHANNELS))
        seen = torch.zeros(N_CHANNELS)
        seen[list(INPUT_CHANNELS[inputs])] = 1.0
        self.register_buffer("input_seen", seen, persistent=False)
        self.rgb_pretrained = False
        if rgb_weights is not None:
            if self.width != 64:
                raise ArchitectureMismatchError(
                    f"ImageNet ResNet-18 weights need width=64, this model has width={width}")
            load_torchvision_weights(self.rgb, rgb_weights)
            self.rgb_pretrained = True

    def architecture(self) -> dict[str, Any]:
        """What a checkpoint must match to load into this model."""
        arch = {"name": "DGTNet", "vehicles": list(self.vehicles), "width": self.width,
                "fc_hidden": self.fc_hidden, "in_channels": N_CHANNELS,
                "heights": "relative to the patch mean"}
        return arch if self.inputs == "rgbd" else {**arch, "inputs": self.inputs}

    def head_index(self, vehicle: str | int) -> int:
        """Column of ``vehicle`` (name, or index into ``config.VEHICLES``) in the output."""
        return head_column(self.vehicles, vehicle)

    def use_live_taps(self, on: bool = True) -> None:
        """Evaluate every convolution with its live taps only (:class:`PatchConv2d`): the
        same network, faster on thin patches, not bit-identical to the full kernels."""
        for m in self.modules():
            if isinstance(m, PatchConv2d):
                m.live_taps = bool(on)

    @torch.no_grad()
    def set_normalization(self, mean: np.ndarray | torch.Tensor,
                          std: np.ndarray | torch.Tensor) -> None:
        """Set the per-channel input mean and standard deviation, each (6,), raw units."""
        mean = torch.as_tensor(np.asarray(mean, dtype=np.float32))
        std = torch.as_tensor(np.asarray(std, dtype=np.float32))
        if mean.shape != (N_CHANNELS,) or std.shape != (N_CHANNELS,):
            raise ValueError(f"mean and std must have shape ({N_CHANNELS},), "
                             f"got {tuple(mean.shape)} and {tuple(std.shape)}")
        if not (torch.isfinite(mean).all() and torch.isfinite(std).all() and (std > 0).all()):
            raise ValueError(f"normalisation must be finite with std > 0, got {mean}, {std}")
        self.input_mean.copy_(mean)
        self.input_std.copy_(std)

    @torch.no_grad()
    def init_heads(self, mean_labels: Sequence[float], weight_scale: float = 0.1) -> None:
        """Start every head at its vehicle's prior: L̂_v = mean training label, flat in z.

        Head v (``w_v · z + b_v`` before the sigmoid) gets b_v ← logit(clip(m_v, 0.01, 0.99))
        and w_v ← weight_scale · w_v, so at the first step L̂_v ≈ m_v for every patch: a
        head on skewed labels (the jeep's: 97 % ≈ 1) then does not saturate early. Why and
        what was measured: docs/training.md.

        Args:
            mean_labels: one mean locomotion label per head, in head order
                (``self.vehicles``), each in [0, 1].
            weight_scale: factor for each head's weights (≥ 0; 1 keeps them as they are).
        """
        means = np.asarray(mean_labels, dtype=np.float64)
        if means.shape != (len(self.vehicle_heads),):
            raise ValueError(f"need one mean label per head, {len(self.vehicle_heads)} "
                             f"({self.vehicles}); got shape {means.shape}")
        if not np.all((means >= 0) & (means <= 1)):  # also catches NaN
            raise ValueError(f"mean labels must be in [0, 1], got {means.tolist()}")
        if not (math.isfinite(weight_scale) and weight_scale >= 0):
            raise ValueError(f"weight_scale must be finite and ≥ 0, got {weight_scale}")
        prior = np.clip(means, *HEAD_PRIOR_CLIP)
        for head, m in zip(self.vehicle_heads, prior, strict=True):
            head.weight.mul_(weight_scale)
            head.bias.fill_(math.log(m / (1.0 - m)))

    def embed(self, x: torch.Tensor) -> torch.Tensor:
        """Shared embedding z: (B, 6, 22, 7) raw patches → (B, fc_hidden)."""
        if x.ndim != 4 or x.shape[1] != N_CHANNELS:
            raise ValueError(f"expected patches (B, {N_CHANNELS}, H, W), got {tuple(x.shape)}")
        x = centre_heights(x)  # H̄ relative to the patch's mean height
        x = (x - self.input_mean[:, None, None]) / self.input_std[:, None, None]
        x = torch.nan_to_num(x, nan=0.0, posinf=0.0, neginf=0.0)
        if self.inputs != "rgbd":  # the channels left out enter as their mean (0 here)
            x = x * self.input_seen[:, None, None]
        features = torch.cat([self.rgb(x[:, RGB_CHANNELS]), self.height(x[:, HEIGHT_CHANNELS])],
                             dim=1)  # (B, 16·width)
        return self.fc(features)  # (B, fc_hidden)

    def heads(self, z: torch.Tensor) -> torch.Tensor:
        """Every vehicle's locomotion from the embedding: (B, fc_hidden) → (B, n_vehicles)."""
        return torch.sigmoid(torch.cat([head(z) for head in self.vehicle_heads], dim=1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """L̂ (B, n_vehicles) in [0, 1] for raw patches x (B, 6, 22, 7)."""
        return self.heads(self.embed(x))


def count_parameters(model: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
