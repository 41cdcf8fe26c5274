"""A C8-equivariant fully convolutional network: all K = 8 headings in one pass.

The literal directional costmap rotates the BEV and slides the 22 × 7 window once per
heading θ_k = 2πk/8, so its cost is linear in K (the paper's Limitations suggest
equivariant networks). Here one network f maps the *unrotated* map to 8 channels per
vehicle, channel k = L̂ for heading θ_k, and is built so that rotating the map rotates
the output field and shifts its channels::

    f(L_g x)_v,k = L_g f(x)_v,k−1,    g = rotation by +45° about the vertical (world frame)

(a "regular representation" of the cyclic group C8 on the heading axis). Channel 0 is
trained as the locomotion of a vehicle heading θ_0 = 0 (+x), and equivariance makes
channel k the same function of the map rotated by −θ_k — the costmap's "rotate by −θ_k,
evaluate, rotate back" — without rotating anything at inference.

The group convolution layers (a rotated filter bank: lifting, group convolution,
BatchNorm shared over a field's 8 headings) are :mod:`dgt_lib.beyond.group_conv`.

Heights: :class:`~dgt_lib.learning.model.DGTNet` sees H̄ minus the mean of its 22 × 7
patch, which depends on the heading and does not exist at a cell. A moving mean (H̄
minus the mean of a disk about each cell) is no substitute: on a plane it is 0
everywhere, so the direction of a slope — what makes uphill cost more than downhill —
would be lost (our first attempt; the trained maps had almost no directional contrast).
Here H̄ enters only through its gradient, as the 8 directional slopes
∂H̄/∂θ_k = ∇H̄ · (cos θ_k, sin θ_k) (central differences,
:func:`~dgt_lib.perception.bev.height_gradient_components`): altitude-free, the same at
training and inference, and itself a regular field (rotating the map by g shifts k by
one), so it enters the first layer through a group convolution beside the lifting of the
five scalar channels R, G, B, σ_H, ‖∇H̄‖ (:data:`INPUT_CHANNELS`).

Training is dense-ready (unlike :mod:`dgt_lib.beyond.dense`): each sample is a square
crop of the real map, of the network's receptive field, around the patch pose, so the
network sees at training exactly the context it sees at inference; convolutions are
"valid" and the crop's single output cell is the sample's prediction. Off-map and
unobserved cells are 0 after normalisation, and inference pads the map with such zeros,
so borders agree too. Measured against DGTNet by ``studies/eval_equivariant.py``.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import asdict, dataclass

import cv2
import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from dgt_lib.beyond.group_conv import N_ROTATIONS, GroupBatchNorm, GroupConv, LiftingConv
from dgt_lib.core.config import VEHICLES
from dgt_lib.core.geometry import GridSpec, heading_bins
from dgt_lib.learning.training import head_prior, masked_loss, regression_metrics
from dgt_lib.perception.bev import GRADIENT, HEIGHT_STD, B, BEVMap, R, height_gradient_components
from dgt_lib.perception.dataset import TEST, TRAIN, VAL, PatchDataset
from dgt_lib.perception.patches import PATCH_COLS, PATCH_RES, PATCH_ROWS, sample_channels

INPUT_CHANNELS = ("R", "G", "B", "sigma_H", "grad_H", "dH_dx", "dH_dy")
"""The network's input map (:func:`input_map`): five scalars, then ∇H̄ [m/m] (a vector)."""
N_SCALARS = 5


# ----------------------------------------------------------------------------- the network


class C8Net(nn.Module):
    """Lifting conv of the scalars plus a group conv of the slopes, ``depth`` group convs
    (each after BatchNorm + ReLU), a 1 × 1 group conv to one regular field per vehicle::

        x (B, 7, H, W) raw input map ─ prepare: scalars normalised, ∇H̄ → 8 slopes,
          0 where unobserved ─ lift k×k (scalars) + group conv k×k (slopes) ─ (B, 8F, ·, ·)
          ─ [GBN, ReLU, group conv k×k] × depth ─ GBN, ReLU ─ head 1×1 ─ sigmoid
          ─ L̂ (B, V, 8, H − RF + 1, W − RF + 1),   RF = 1 + (depth + 1)(k − 1)

    Output [b, v, k, i, j]: vehicle ``vehicles[v]`` heading θ_k at the cell whose
    receptive field starts at (i, j) ("valid" convolutions). Normalisation buffers
    (scalar mean and std, one slope scale, no mean: a mean would break the symmetry) are
    set from the training map and saved in the state dict, as in DGTNet.
    """

    def __init__(self, vehicles: tuple[str, ...] | list[str] = VEHICLES, fields: int = 8,
                 depth: int = 4, kernel: int = 5, rgb: bool = True) -> None:
        super().__init__()
        self.vehicles = tuple(vehicles)
        self.fields, self.depth, self.kernel = int(fields), int(depth), int(kernel)
        self.rgb = bool(rgb)  # False: R, G, B are zeroed (an ablation: geometry only)
        self.lift = LiftingConv(N_SCALARS, fields, kernel)
        self.lift_slopes = GroupConv(1, fields, kernel)
        self.blocks = nn.ModuleList(
            nn.Sequential(GroupBatchNorm(fields), nn.ReLU(), GroupConv(fields, fields, kernel))
            for _ in range(depth))
        self.norm = GroupBatchNorm(fields)
        self.head = GroupConv(fields, len(self.vehicles), 1, bias=True)
        self.register_buffer("input_mean", torch.zeros(N_SCALARS))
        self.register_buffer("input_std", torch.ones(N_SCALARS))
        self.register_buffer("slope_scale", torch.ones(()))
        thetas = torch.tensor(heading_bins(N_ROTATIONS), dtype=torch.float32)
        self.register_buffer("directions", torch.stack([torch.cos(thetas), torch.sin(thetas)]))

    @property
    def receptive_field(self) -> int:
        """Side [cells] of the square of input that one output cell sees."""
        return 1 + (self.depth + 1) * (self.kernel - 1)

    def architecture(self) -> dict[str, object]:
        return {"name": "C8Net", "vehicles": list(self.vehicles), "fields": self.fields,
                "depth": self.depth, "kernel": self.kernel, "rgb": self.rgb}

    def prepare(self, x: torch.Tensor, observed: torch.Tensor) -> torch.Tensor:
        """Raw input maps (B, 7, H, W) (:data:`INPUT_CHANNELS`) and observed (B, H, W) →
        (B, 5 + 8, H, W): normalised scalars and the slopes ∂H̄/∂θ_k / scale, 0 where
        unobserved."""
        mean, std = self.input_mean[:, None, None], self.input_std[:, None, None]
        scalars = (x[:, :N_SCALARS] - mean) / std
        if not self.rgb:
            scalars = torch.cat([torch.zeros_like(scalars[:, :3]), scalars[:, 3:]], dim=1)
        slopes = torch.einsum("bchw,ck->bkhw", x[:, N_SCALARS:], self.directions)
        out = torch.cat([scalars, slopes / self.slope_scale], dim=1)
        out = torch.where(observed[:, None], out, torch.zeros((), dtype=out.dtype))
        return torch.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)

    def logits(self, x: torch.Tensor) -> torch.Tensor:
        """Prepared input (B, 13, H, W) → logits (B, V, 8, H − RF + 1, W − RF + 1)."""
        h = self.lift(x[:, :N_SCALARS]) + self.lift_slopes(x[:, N_SCALARS:])
        for block in self.blocks:
            h = block(h)
        out = self.head(F.relu(self.norm(h)))
        return out.view(out.shape[0], len(self.vehicles), N_ROTATIONS, *out.shape[-2:])

    def forward(self, x: torch.Tensor, observed: torch.Tensor) -> torch.Tensor:
        """L̂ (B, V, 8, H − RF + 1, W − RF + 1) in [0, 1] from raw x and observed."""
        return torch.sigmoid(self.logits(self.prepare(x, observed)))

    @torch.no_grad()
    def init_heads(self, mean_labels: list[float], weight_scale: float = 0.1) -> None:
        """Each vehicle's field starts at its prior, as :meth:`DGTNet.init_heads`."""
        prior = np.clip(np.asarray(mean_labels, np.float64), 0.01, 0.99)
        self.head.weight.mul_(weight_scale)
        self.head.bias.copy_(torch.tensor(np.log(prior / (1 - prior)), dtype=torch.float32))


# ----------------------------------------------------------------------------- inputs


def input_map(bev: BEVMap) -> np.ndarray:
    """The network's input map (7, H, W) float32 of a BEV (:data:`INPUT_CHANNELS`):
    R, G, B, σ_H, ‖∇H̄‖ as they are, then ∂H̄/∂x and ∂H̄/∂y [m/m]; 0 where unobserved."""
    d_dy, d_dx = height_gradient_components(bev.mean_height, bev.observed, bev.grid.resolution)
    scalars = bev.channels[[R, R + 1, B, HEIGHT_STD, GRADIENT]]
    return np.concatenate([scalars, np.stack([d_dx, d_dy])]).astype(np.float32)


def heading_crops(channels: np.ndarray, observed: np.ndarray, grid: GridSpec,
                  poses: np.ndarray, size: int, bins: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Square crops (N, 7, size, size) and observed (N, size, size) of an :func:`input_map`
    (7, H, W) on ``grid`` around each pose (x, y, θ), rotated so that the pose's heading θ
    lies at θ_k for the crop's ``bins[n]`` = k (default 0): crop pixel (r, c) is the world
    point (x, y) + R(φ)·((c − m)·res, (r − m)·res), φ = θ − θ_k, m = (size − 1)/2, sampled
    bilinearly (:func:`~dgt_lib.perception.patches.sample_channels`), and ∇H̄ is turned by
    −φ into the crop's frame. Channel k of the network at the crop's centre is then the
    locomotion of that pose."""
    poses = np.asarray(poses, np.float64)
    bins = np.zeros(len(poses), np.int64) if bins is None else np.asarray(bins)
    m, res = (size - 1) / 2.0, grid.resolution
    r, c = np.mgrid[0:size, 0:size].astype(np.float64)
    dx, dy = ((c - m) * res).ravel(), ((r - m) * res).ravel()
    phi = poses[:, 2] - heading_bins(N_ROTATIONS)[bins]
    cos, sin = np.cos(phi)[:, None], np.sin(phi)[:, None]
    x = poses[:, :1] + cos * dx - sin * dy  # (N, size²)
    y = poses[:, 1:2] + sin * dx + cos * dy
    values, seen = sample_channels(channels, observed, grid, x, y)  # (7, N, size²)
    gx, gy = values[N_SCALARS].copy(), values[N_SCALARS + 1].copy()
    values[N_SCALARS], values[N_SCALARS + 1] = cos * gx + sin * gy, -sin * gx + cos * gy
    crops = np.ascontiguousarray(np.moveaxis(values, 0, 1))
    return crops.reshape(len(poses), -1, size, size), seen.reshape(len(poses), size, size)


def input_statistics(channels: np.ndarray, observed: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, float]:
    """Scalar mean and std (5,) and the slope scale (RMS of ∇H̄'s components) over the
    observed cells of an :func:`input_map`."""
    values = channels[:, observed].astype(np.float64)
    std = values[:N_SCALARS].std(axis=1)
    slope = float(np.sqrt(np.mean(values[N_SCALARS:] ** 2)))
    return (values[:N_SCALARS].mean(axis=1).astype(np.float32),
            np.where(std > 1e-6, std, 1).astype(np.float32), max(slope, 1e-6))


def equivariance_error(model: C8Net, bev: BEVMap, n: int = 512, seed: int = 0
                       ) -> dict[str, float]:
    """How far a network is from equivariant on a real map: mean and max
    |L̂(L_{g^k} map)_{j+k} − L̂(map)_j| over ``n`` random observed cells, every vehicle and
    heading j, for k = 1 (45°) and k = 2 (90°), from :func:`heading_crops` about each
    cell (θ = 0) rotated to bin k."""
    channels = input_map(bev)
    rng = np.random.default_rng(seed)
    rows, cols = np.nonzero(bev.observed)
    pick = rng.choice(len(rows), min(n, len(rows)), replace=False)
    x, y = bev.grid.cell_to_xy(rows[pick], cols[pick])
    poses = np.stack([x, y, np.zeros(len(pick))], axis=1)
    model.eval()
    outs = []
    with torch.no_grad():
        for k in range(3):
            crops, obs = heading_crops(channels, bev.observed, bev.grid, poses,
                                       model.receptive_field, np.full(len(pick), k))
            outs.append(model(torch.from_numpy(crops), torch.from_numpy(obs))[..., 0, 0].numpy())
    out = {}
    for k, name in ((1, "45"), (2, "90")):
        d = np.abs(outs[k] - np.roll(outs[0], k, axis=2))
        out[f"mean_{name}"], out[f"max_{name}"] = float(d.mean()), float(d.max())
    return out


# ----------------------------------------------------------------------------- training


@dataclass(frozen=True)
class EquivariantConfig:
    """Architecture and training of :class:`C8Net` (our settings, not the paper's)."""

    fields: int = 8  # regular fields per layer (8 channels each)
    depth: int = 4  # group convolutions after the lifting layer
    kernel: int = 5  # filter side [cells]; RF = 1 + (depth + 1)(kernel − 1) = 21 cells = 8.4 m
    epochs: int = 10  # ~8 min on the demo data, 2 shared cores
    batch_size: int = 64
    learning_rate: float = 2e-3  # Adam, cosine schedule to 0
    rotate_augment: bool = True  # random k·45° per sample, channel k trained
    rgb: bool = True  # False: colour zeroed (ablation)


@dataclass
class EquivariantResult:
    """A trained :class:`C8Net`: weights of the best validation epoch, per-epoch history,
    test metrics per vehicle (exact-θ crops, channel 0), the config and seed."""

    model: C8Net
    history: list[dict[str, float]]
    best_epoch: int
    metrics: dict[str, dict[str, float]]
    config: EquivariantConfig
    seed: int

    def to_dict(self) -> dict[str, object]:
        return {"state_dict": self.model.state_dict(), "architecture": self.model.architecture(),
                "history": self.history, "best_epoch": self.best_epoch,
                "metrics": self.metrics, "config": asdict(self.config), "seed": self.seed}

    @classmethod
    def from_dict(cls, d: dict) -> EquivariantResult:
        arch = d["architecture"]
        model = C8Net(arch["vehicles"], arch["fields"], arch["depth"], arch["kernel"],
                      arch.get("rgb", True))
        model.load_state_dict(d["state_dict"])
        model.eval()
        return cls(model, d["history"], d["best_epoch"], d["metrics"],
                   EquivariantConfig(**d["config"]), d["seed"])


def _batch(model: C8Net, channels: np.ndarray, bev: BEVMap, poses: np.ndarray,
           bins: np.ndarray) -> torch.Tensor:
    """L̂ (B, V, 8) at the centres of the crops of ``poses`` rotated to ``bins``."""
    crops, observed = heading_crops(channels, bev.observed, bev.grid, poses,
                                    model.receptive_field, bins)
    out = model(torch.from_numpy(crops), torch.from_numpy(observed))
    return out[:, :, :, 0, 0]


@torch.no_grad()
def predict_samples(model: C8Net, bev: BEVMap, poses: np.ndarray,
                    bins: np.ndarray | None = None, batch_size: int = 512) -> np.ndarray:
    """L̂ (N, V) of each pose's own heading: the crop rotated to ``bins[n]`` (default 0),
    channel ``bins[n]``."""
    model.eval()
    channels = input_map(bev)
    bins = np.zeros(len(poses), np.int64) if bins is None else np.asarray(bins)
    out = []
    for s in range(0, len(poses), batch_size):
        b = bins[s : s + batch_size]
        pred = _batch(model, channels, bev, poses[s : s + batch_size], b)  # (n, V, 8)
        out.append(pred[torch.arange(len(b)), :, torch.from_numpy(b)].numpy())
    return np.concatenate(out) if out else np.zeros((0, len(model.vehicles)), np.float32)


def evaluate(model: C8Net, bev: BEVMap, part: PatchDataset) -> dict[str, dict[str, float]]:
    """Per-vehicle :func:`~dgt_lib.learning.training.regression_metrics` of the model's
    own head on ``part`` (crops at each pose's exact θ, channel 0)."""
    pred = predict_samples(model, bev, part.pose)
    out = {}
    for j, name in enumerate(model.vehicles):
        sel = part.vehicle == VEHICLES.index(name)
        if sel.any():
            out[name] = regression_metrics(pred[sel, j], part.labels[sel])
    return out


def train_equivariant(dataset: PatchDataset, bev: BEVMap, cfg: EquivariantConfig, *,
                      seed: int = 0, progress: bool = True) -> EquivariantResult:
    """Train a multi-task :class:`C8Net` on the dataset's poses over its map ``bev`` (the
    training world's raw BEV) with the masked loss of
    :func:`~dgt_lib.learning.training.masked_loss`, on the dataset's own train/val/test
    split. Each step crops the map around the batch's poses (receptive-field square),
    rotated to a random heading bin k (``rotate_augment``) whose channel is trained."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    channels = input_map(bev)
    model = C8Net(VEHICLES, cfg.fields, cfg.depth, cfg.kernel, cfg.rgb)
    mean, std, slope = input_statistics(channels, bev.observed)
    model.input_mean.copy_(torch.from_numpy(mean))
    model.input_std.copy_(torch.from_numpy(std))
    model.slope_scale.fill_(slope)
    train_idx = np.flatnonzero(dataset.split == TRAIN)
    val_idx = np.flatnonzero(dataset.split == VAL)
    model.init_heads(head_prior(dataset, train_idx, VEHICLES))
    opt = torch.optim.Adam(model.parameters(), lr=cfg.learning_rate)
    steps = cfg.epochs * max(len(train_idx) // cfg.batch_size, 1)
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda t: 0.5 * (1 + math.cos(math.pi * min(t, steps) / steps)))
    labels = torch.from_numpy(dataset.labels.astype(np.float32))
    heads = torch.from_numpy(dataset.vehicle.astype(np.int64))
    history, best_state, best_val, best_epoch = [], None, math.inf, 0
    for epoch in range(1, cfg.epochs + 1):
        t0, total = time.perf_counter(), 0.0
        model.train()
        order = rng.permutation(train_idx)
        n_batches = max(len(order) // cfg.batch_size, 1)
        for b in range(n_batches):
            idx = order[b * cfg.batch_size : (b + 1) * cfg.batch_size]
            bins = (rng.integers(0, N_ROTATIONS, len(idx)) if cfg.rotate_augment
                    else np.zeros(len(idx), np.int64))
            pred = _batch(model, channels, bev, dataset.pose[idx], bins)  # (B, V, 8)
            pred = pred[torch.arange(len(idx)), :, torch.from_numpy(bins)]  # (B, V)
            loss = masked_loss(pred, labels[idx], heads[idx])
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            sched.step()
            total += loss.item()
        val_pred = predict_samples(model, bev, dataset.pose[val_idx])
        val = masked_loss(torch.from_numpy(val_pred), labels[val_idx], heads[val_idx]).item()
        history.append({"epoch": epoch, "train_loss": total / n_batches, "val_loss": val,
                        "seconds": time.perf_counter() - t0})
        if progress:
            print(f"[equivariant] epoch {epoch}: train {total / n_batches:.4f} val {val:.4f} "
                  f"({history[-1]['seconds']:.0f} s)", flush=True)
        if val < best_val or best_state is None:  # (NaN without validation samples)
            best_val, best_epoch = val, epoch
            best_state = copy.deepcopy(model.state_dict())
    model.load_state_dict(best_state)
    model.eval()
    metrics = evaluate(model, bev, dataset.subset(dataset.split == TEST))
    return EquivariantResult(model, history, best_epoch, metrics, cfg, seed)


# ----------------------------------------------------------------------------- inference


@torch.no_grad()
def equivariant_locomotion(model: C8Net, bev: BEVMap, tile: int = 256) -> np.ndarray:
    """L̂ (V, 8, H, W) of every cell and heading θ_k in one pass over ``bev``'s
    :func:`input_map`, zero-padded by RF // 2 so that every cell is an output cell;
    evaluated in tiles of ``tile`` output rows (same result, bounded memory)."""
    model.eval()
    pad = model.receptive_field // 2
    x = model.prepare(torch.from_numpy(input_map(bev))[None],
                      torch.from_numpy(bev.observed)[None])
    x = F.pad(x, (pad, pad, pad, pad))  # zeros = unobserved, as off-map crops in training
    h = bev.grid.height
    out = [model.logits(x[:, :, s : s + tile + 2 * pad])[0] for s in range(0, h, tile)]
    return torch.sigmoid(torch.cat(out, dim=-2)).numpy()


def footprint_kernel(theta: float, resolution: float = PATCH_RES,
                     supersample: int = 4) -> np.ndarray:
    """(S, S) weights [cells] of the 8.8 m × 2.8 m patch footprint turned to heading θ [rad],
    centred: the fraction of each cell (``supersample``² points) inside the rectangle
    |forward| ≤ 4.4 m, |left| ≤ 1.4 m. Rows = y, columns = x, as on a GridSpec. At θ = 0
    it sums to 22 × 7 = 154."""
    half_f, half_l = PATCH_ROWS * resolution / 2, PATCH_COLS * resolution / 2
    radius = int(np.ceil(np.hypot(half_f, half_l) / resolution))
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    off = np.arange(-radius, radius + 1)
    dy = (off[:, None, None, None] + sub[None, None, :, None]) * resolution  # (S, 1, s, 1)
    dx = (off[None, :, None, None] + sub[None, None, None, :]) * resolution  # (1, S, 1, s)
    forward = dx * np.cos(theta) + dy * np.sin(theta)
    left = -dx * np.sin(theta) + dy * np.cos(theta)
    inside = (np.abs(forward) <= half_f) & (np.abs(left) <= half_l)
    return inside.mean(axis=(2, 3))


def footprint_average(locomotion: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """The literal procedure's last step on a one-pass field: each cell takes the mean of
    the predictions of every footprint covering it (``valid`` windows, centred on (H, W)
    cells), layer k with the footprint turned to θ_k (:func:`footprint_kernel`):
    (V, 8, H, W) → (V, 8, H, W) float32. The rectangle is symmetric about its centre, so
    "windows covering a cell" is a correlation with the same kernel."""
    out = np.empty(locomotion.shape, np.float32)
    w = valid.astype(np.float64)
    for k, theta in enumerate(heading_bins(N_ROTATIONS)):
        kernel = footprint_kernel(float(theta))
        count = cv2.filter2D(w, -1, kernel, borderType=cv2.BORDER_CONSTANT)
        for v in range(locomotion.shape[0]):
            total = cv2.filter2D(locomotion[v, k] * w, -1, kernel,
                                 borderType=cv2.BORDER_CONSTANT)
            out[v, k] = total / np.maximum(count, 1e-9)
    return out


def equivariant_costmap(bev: BEVMap, model: C8Net, average: bool = True) -> np.ndarray:
    """The directional costmap (V, 8, H, W) float32, C = 1 − L̂, from one pass: layer k =
    heading θ_k = 2πk/8 as in :func:`~dgt_lib.mapping.costmap.directional_costmap`;
    1 on unobserved cells. ``average``: each cell's L̂ is the mean over the footprints
    covering it, as in the paper's procedure (:func:`footprint_average`); else the
    prediction at the cell itself."""
    locomotion = equivariant_locomotion(model, bev)
    if average:
        locomotion = footprint_average(locomotion, np.ones(bev.grid.shape, bool))
    cost = 1.0 - np.clip(locomotion, 0.0, 1.0)
    cost[:, :, ~bev.observed] = 1.0
    return cost.astype(np.float32)
