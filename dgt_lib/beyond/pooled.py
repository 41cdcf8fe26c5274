"""A window network built to be evaluated densely, exactly.

The literal costmap runs the network once per 22 × 7 window, every window position, every
heading. :mod:`dgt_lib.beyond.dense` shows that :class:`~dgt_lib.learning.model.DGTNet`
cannot be evaluated any other way: its ResNet sees each window through zero padding, so
a fully convolutional pass over the map computes a different function. ``PooledNet`` is
the network that can: every operation on a window is either local (a "valid"
convolution, which gives the same value at a cell whatever window it is cut in, as long
as the window carries its context) or a mean over the window (a box filter over the map).
Per window W with top-left pixel (a, b) of the rotated map::

    f = trunk(map)                       per cell: 3 × 3 valid convolutions, BN, ReLU
    z_W = [mean_{front half of W} f, mean_{rear half of W} f]     (2·width,)
    L̂_W = σ(heads(ReLU(FC z_W)))                                  (V,)

The literal procedure cuts each window with a margin of :attr:`PooledNet.margin` cells
of context (:func:`~dgt_lib.perception.patches.extract_patches` with ``margin``) and runs
the whole network on it. The dense procedure (:meth:`PooledNet.window_field`) runs the
trunk once over the rotated map, takes both half-window means as box filters
(``avg_pool2d``) and the FC layer and heads as 1 × 1 convolutions: the same numbers up
to float rounding, at every window position at once. The front/rear halves keep where
along the heading a feature lies (a step under the front wheels is not one behind the
rear); a single mean would lose it.

Heights enter as slopes, not as H̄: DGTNet subtracts each patch's mean height, which
depends on the window and has no per-cell equivalent. Here the first step computes
∂H̄/∂forward and ∂H̄/∂left by central differences in the window's frame (rows point
forward, columns to the right, as in a patch), 0 where a neighbour is unobserved:
altitude-free and local. The other inputs are R, G, B, σ_H, ‖∇H̄‖ (normalised) and the
observed mask itself, all 0 where unobserved, so off-map padding and unobserved cells are
the same input.

Training (:func:`train_pooled`) runs the library's own loop,
:func:`~dgt_lib.learning.run.train_network` around :func:`~dgt_lib.learning.training.fit`
(the same masked loss, recipe and mirror augmentation as DGTNet), on a dataset whose patches
are the margin crops with the observed mask as a 7th channel (:func:`context_dataset`).
Measured against DGTNet by ``studies/eval_pooled.py``; :func:`bfloat16_copy` trades
exactness (mean |ΔC| < 10⁻³) for a ~5× faster trunk on CPUs with AMX
(``benchmarks/bench_costmap.py --bf16``).
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from dgt_lib.core.config import VEHICLES, TrainConfig
from dgt_lib.learning.checkpoints import TrainResult
from dgt_lib.learning.model import HEAD_PRIOR_CLIP, head_column
from dgt_lib.learning.run import train_network
from dgt_lib.learning.training import TrainingSet
from dgt_lib.perception.bev import BEVMap
from dgt_lib.perception.dataset import PatchDataset
from dgt_lib.perception.patches import PATCH_COLS, PATCH_RES, PATCH_ROWS, extract_patches

HEIGHT = 3
"""Index of H̄ among the BEV channels R, G, B, H̄, σ_H, ‖∇H̄‖."""
SCALARS = (0, 1, 2, 4, 5)
"""BEV channels the network reads as they are (normalised): R, G, B, σ_H, ‖∇H̄‖."""
N_INPUTS = len(SCALARS) + 3
"""Trunk inputs per cell: the five scalars, ∂H̄/∂forward, ∂H̄/∂left, observed."""
FRONT_ROWS = PATCH_ROWS // 2
"""Rows of the front half of a window (the rear half has the other 11)."""


class PooledNet(nn.Module):
    """Local trunk, front/rear window means, shared FC, one sigmoid head per vehicle::

        crop (B, 7, 22 + 2m, 7 + 2m): 6 BEV channels + observed, m = depth + 1
          ─ prepare: slopes by central differences, scalars normalised, 0 where unobserved
          ─ (B, 8, 20 + 2m, 5 + 2m) ─ conv 3×3 ─ [BN, ReLU, conv 3×3] × (depth − 1) ─ BN, ReLU
          ─ f (B, width, 22, 7) ─ means of rows 0–10 and 11–21 ─ (B, 2·width)
          ─ FC + ReLU ─ (B, fc_hidden) ─ heads ─ sigmoid ─ L̂ (B, V)

    All convolutions are "valid"; the FC layer and the heads are 1 × 1 convolutions, so
    :meth:`window_field` can run them on a field of windows. Normalisation buffers
    (``input_mean``/``input_std`` of the five scalars, ``slope_scale``) are set from the
    training crops (:meth:`set_normalization`) and saved in the state dict.

    ``depth`` 6 (a 15 × 15-cell, 6 m view per trunk feature, margin 7): of depth 4, 6, 8 and
    width 64 at depth 4, trained on the ``demo`` data (3 seeds each), it came closest to the
    ridge's measured ground truth (``studies/eval_pooled.py``; docs/speed.md). Picked on those
    results, so the ``paper`` profile's seeds are its independent check.
    """

    def __init__(self, vehicles: Sequence[str] = VEHICLES, width: int = 32, depth: int = 6,
                 fc_hidden: int = 64) -> None:
        super().__init__()
        self.vehicles = tuple(vehicles)
        unknown = [v for v in self.vehicles if v not in VEHICLES]
        if not self.vehicles or unknown or len(set(self.vehicles)) != len(self.vehicles):
            raise ValueError(f"vehicles must be distinct names from {VEHICLES}, got {vehicles}")
        if width < 1 or depth < 1 or fc_hidden < 1:
            raise ValueError(f"width, depth and fc_hidden must be ≥ 1, got {width}, {depth}, "
                             f"{fc_hidden}")
        self.width, self.depth, self.fc_hidden = int(width), int(depth), int(fc_hidden)
        self.stem = nn.Conv2d(N_INPUTS, self.width, 3)
        self.blocks = nn.ModuleList(
            nn.Sequential(nn.BatchNorm2d(self.width), nn.ReLU(),
                          nn.Conv2d(self.width, self.width, 3))
            for _ in range(self.depth - 1))
        self.norm = nn.BatchNorm2d(self.width)
        self.fc = nn.Conv2d(2 * self.width, self.fc_hidden, 1)
        self.head = nn.Conv2d(self.fc_hidden, len(self.vehicles), 1)
        self.register_buffer("input_mean", torch.zeros(len(SCALARS)))
        self.register_buffer("input_std", torch.ones(len(SCALARS)))
        self.register_buffer("slope_scale", torch.ones(()))

    @classmethod
    def from_state_dict(cls, state: dict[str, torch.Tensor],
                        vehicles: Sequence[str] = VEHICLES) -> PooledNet:
        """A network of the state dict's size (width, depth, fc_hidden read off its weights)
        with its weights, in eval mode; ``vehicles`` name its heads, in order."""
        depth = 1 + len({k.split(".")[1] for k in state if k.startswith("blocks.")})
        model = cls(vehicles, width=state["stem.weight"].shape[0], depth=depth,
                    fc_hidden=state["fc.weight"].shape[0])
        model.load_state_dict(state)
        return model.eval()

    @property
    def margin(self) -> int:
        """Cells of context a window needs on every side: 1 (the slopes) + 1 per convolution."""
        return 1 + self.depth

    @property
    def device(self) -> torch.device:
        """Where the network's weights are (a network trained on a GPU stays there): the
        map-level methods move their input there and hand back numpy arrays on the CPU."""
        return self.input_mean.device

    def architecture(self) -> dict[str, object]:
        return {"name": "PooledNet", "vehicles": list(self.vehicles), "width": self.width,
                "depth": self.depth, "fc_hidden": self.fc_hidden}

    def head_index(self, vehicle: str | int) -> int:
        """Column of ``vehicle`` (name or index into ``config.VEHICLES``) in the output."""
        return head_column(self.vehicles, vehicle)

    @torch.no_grad()
    def set_normalization(self, crops: np.ndarray, index: np.ndarray | None = None) -> None:
        """Scalar mean and std and the slope scale from the observed cells of training crops
        (N, 7, ·, ·) (``index``: which); the slope scale is the RMS of ‖∇H̄‖ [m/m]."""
        x = crops if index is None else crops[np.sort(np.asarray(index))]
        observed = np.asarray(x[:, -1], bool)
        values = np.stack([np.asarray(x[:, c], np.float64)[observed] for c in SCALARS])
        if values.shape[1] == 0:
            raise ValueError("no observed cell in the crops to normalise with")
        std = values.std(axis=1)
        self.input_mean.copy_(torch.tensor(values.mean(axis=1), dtype=torch.float32))
        self.input_std.copy_(torch.tensor(np.where(std > 1e-6, std, 1.0), dtype=torch.float32))
        self.slope_scale.fill_(max(float(np.sqrt(np.mean(values[-1] ** 2))), 1e-6))

    @torch.no_grad()
    def init_heads(self, mean_labels: Sequence[float], weight_scale: float = 0.1) -> None:
        """Every head starts at its vehicle's prior, as :meth:`DGTNet.init_heads`."""
        prior = np.clip(np.asarray(mean_labels, np.float64), *HEAD_PRIOR_CLIP)
        self.head.weight.mul_(weight_scale)
        self.head.bias.copy_(torch.tensor(np.log(prior / (1 - prior)), dtype=torch.float32))

    def prepare(self, x: torch.Tensor) -> torch.Tensor:
        """Raw maps (B, 7, H, W) (6 BEV channels, observed) → trunk input (B, 8, H − 2, W − 2):
        normalised scalars, ∂H̄/∂forward and ∂H̄/∂left over the slope scale (row r − 1 is
        ahead of row r, column c − 1 left of column c), observed; 0 where unobserved."""
        observed = x[:, -1] > 0.5
        seen = observed[:, 1:-1, 1:-1]
        h = torch.nan_to_num(x[:, HEIGHT])
        step = 2 * PATCH_RES * self.slope_scale
        forward = (h[:, :-2, 1:-1] - h[:, 2:, 1:-1]) / step
        left = (h[:, 1:-1, :-2] - h[:, 1:-1, 2:]) / step
        ok_forward = observed[:, :-2, 1:-1] & observed[:, 2:, 1:-1]
        ok_left = observed[:, 1:-1, :-2] & observed[:, 1:-1, 2:]
        scalars = x[:, list(SCALARS), 1:-1, 1:-1]
        scalars = (scalars - self.input_mean[:, None, None]) / self.input_std[:, None, None]
        zero = torch.zeros((), dtype=x.dtype, device=x.device)
        out = torch.cat([torch.where(seen[:, None], scalars, zero),
                         torch.where(ok_forward, forward, zero)[:, None],
                         torch.where(ok_left, left, zero)[:, None],
                         seen[:, None].to(x.dtype)], dim=1)
        return torch.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)

    def trunk(self, x: torch.Tensor) -> torch.Tensor:
        """Raw maps (B, 7, H, W) → features (B, width, H − 2m, W − 2m). The inputs are
        prepared in float32 (heights of tens of metres need it for their slopes), then cast
        to the weights' dtype (:func:`bfloat16_copy`)."""
        p = self.prepare(x.float())
        if self.stem.weight.dtype != torch.float32:
            p = p.to(self.stem.weight.dtype).contiguous(memory_format=torch.channels_last)
        f = self.stem(p)
        for block in self.blocks:
            f = block(f)
        return F.relu(self.norm(f))

    def heads(self, z: torch.Tensor) -> torch.Tensor:
        """Window embeddings (B, 2·width, ...) → L̂ (B, V, ...) in [0, 1]."""
        return torch.sigmoid(self.head(F.relu(self.fc(z))))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """L̂ (B, V) of windows with context, x (B, 7, 22 + 2m, 7 + 2m)."""
        m = self.margin
        if x.ndim != 4 or x.shape[1:] != (N_INPUTS - 1, PATCH_ROWS + 2 * m, PATCH_COLS + 2 * m):
            raise ValueError(f"expected crops (B, 7, {PATCH_ROWS + 2 * m}, "
                             f"{PATCH_COLS + 2 * m}), got {tuple(x.shape)}")
        f = self.trunk(x)  # (B, width, 22, 7)
        z = torch.cat([f[:, :, :FRONT_ROWS].mean(dim=(2, 3)),
                       f[:, :, FRONT_ROWS:].mean(dim=(2, 3))], dim=1)
        return self.heads(z[:, :, None, None])[:, :, 0, 0].float()

    @torch.no_grad()
    def window_field(self, channels: np.ndarray, observed: np.ndarray,
                     windows: np.ndarray | None = None, tile: int = 64) -> np.ndarray:
        """L̂ of the 22 × 7 windows of a rotated map, densely: channels (6, D_r, D_c) and
        observed (D_r, D_c) → (V, D_r − 21, D_c − 6), element [:, a, b] for the window with
        top-left pixel (a, b) (the indexing of
        :func:`~dgt_lib.perception.patches.sliding_windows`). ``windows`` (same shape, bool):
        only those are needed, the field is 0 at every other window. The map is padded with
        ``margin`` unobserved cells (:meth:`padded_window_field`)."""
        m = self.margin
        x = np.concatenate([np.asarray(channels, np.float32),
                            np.asarray(observed, np.float32)[None]])
        return self.padded_window_field(np.pad(x, ((0, 0), (m, m), (m, m))), windows, tile)

    @torch.no_grad()
    def padded_window_field(self, x: np.ndarray, windows: np.ndarray | None = None,
                            tile: int = 64) -> np.ndarray:
        """:meth:`window_field` of a map that already carries its context: x (7, R, C), the
        6 BEV channels and observed, → (V, R − 21 − 2m, C − 6 − 2m), element [:, a, b] for
        the window whose context starts at x[:, a, b]. Each tile of ``tile`` window rows is
        evaluated over the columns its needed windows span."""
        self.eval()
        m = self.margin
        n_a, n_b = x.shape[1] - PATCH_ROWS + 1 - 2 * m, x.shape[2] - PATCH_COLS + 1 - 2 * m
        windows = np.ones((n_a, n_b), bool) if windows is None else np.asarray(windows, bool)
        t = torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))[None].to(self.device)
        out = torch.zeros((len(self.vehicles), n_a, n_b))
        for s in range(0, n_a, tile):
            cols = np.flatnonzero(windows[s : s + tile].any(axis=0))
            if len(cols) == 0:
                continue
            # extend the tile to a multiple of 16 × 32 windows: region shapes then repeat
            # from call to call and torch reuses its convolution plans (the demo drive's
            # incremental update: 230 → 203 ms median, bench_incremental.py --pooled)
            r0, r1 = _bucket(s, min(s + tile, n_a), n_a, 16)
            c0, c1 = _bucket(int(cols[0]), int(cols[-1]) + 1, n_b, 32)
            rows = r1 - r0
            f = self.trunk(t[:, :, r0 : r1 + PATCH_ROWS - 1 + 2 * m,
                             c0 : c1 + PATCH_COLS - 1 + 2 * m])
            halves = half_window_means(f)
            z = torch.cat([halves[:, :, :rows], halves[:, :, FRONT_ROWS : FRONT_ROWS + rows]],
                          dim=1)
            out[:, r0:r1, c0:c1] = self.heads(z)[0].float().cpu()
        out[:, ~torch.from_numpy(windows)] = 0.0
        return out.numpy()

    @torch.no_grad()
    def empty_window(self) -> np.ndarray:
        """L̂ (V,) of a window whose context holds no observed cell (every input is 0)."""
        m = self.margin
        x = torch.zeros((1, N_INPUTS - 1, PATCH_ROWS + 2 * m, PATCH_COLS + 2 * m),
                        device=self.device)
        self.eval()
        return self(x)[0].cpu().numpy()

    @torch.no_grad()
    def literal_window_field(self, channels: np.ndarray, observed: np.ndarray,
                             windows: np.ndarray, batch_size: int = 1024) -> np.ndarray:
        """The reference for :meth:`window_field`: each window of ``windows`` (n_a, n_b)
        bool cut out with its margin and run through :meth:`forward` on its own. Returns
        (V, n_a, n_b), 0 at windows not asked for."""
        self.eval()
        m = self.margin
        x = np.concatenate([np.asarray(channels, np.float32),
                            np.asarray(observed, np.float32)[None]])
        x = np.pad(x, ((0, 0), (m, m), (m, m)))
        crops = np.lib.stride_tricks.sliding_window_view(
            x, (PATCH_ROWS + 2 * m, PATCH_COLS + 2 * m), axis=(1, 2))
        field = np.zeros((len(self.vehicles), *windows.shape), np.float32)
        a, b = np.nonzero(windows)
        for s in range(0, len(a), batch_size):
            sa, sb = a[s : s + batch_size], b[s : s + batch_size]
            batch = torch.from_numpy(np.ascontiguousarray(np.moveaxis(crops[:, sa, sb], 0, 1)))
            field[:, sa, sb] = self(batch.to(self.device)).cpu().numpy().T
        return field


def bfloat16_copy(model: PooledNet) -> PooledNet:
    """A copy of ``model`` for fast inference: weights in bfloat16, feature maps channels-last
    (on CPUs with AMX, e.g. this machine's Xeon, oneDNN then runs the trunk ~5× faster than
    float32); the inputs are still prepared in float32 and the outputs are float32. Not exact:
    ``benchmarks/bench_costmap.py --bf16`` measures |ΔC| against the float32 literal
    procedure."""
    fast = copy.deepcopy(model).eval()
    keep = {k: getattr(model, k) for k in ("input_mean", "input_std", "slope_scale")}
    fast = fast.to(torch.bfloat16).to(memory_format=torch.channels_last)
    for k, v in keep.items():  # the normalisation stays float32
        setattr(fast, k, v.clone())
    return fast


def _bucket(lo: int, hi: int, n: int, q: int) -> tuple[int, int]:
    """[lo, hi) extended to a length that is a multiple of ``q`` (at most ``n``), kept within
    [0, n) by moving its start back where it would end past n."""
    length = min(-(-(hi - lo) // q) * q, n)
    lo = max(min(lo, n - length), 0)
    return lo, lo + length


def half_window_means(f: torch.Tensor) -> torch.Tensor:
    """Mean of features (B, C, H, W) over every 11 × 7 box: (B, C, H − 10, W − 6), element
    [..., p, q] over rows p … p + 10 and columns q … q + 6 — a window's front half at its
    top-left pixel, its rear half 11 rows lower. Separable box filters as depthwise
    convolutions (torch's ``avg_pool2d`` is ~8× slower here on a CPU)."""
    c = f.shape[1]
    rows = torch.full((c, 1, FRONT_ROWS, 1), 1.0 / FRONT_ROWS, dtype=f.dtype, device=f.device)
    cols = torch.full((c, 1, 1, PATCH_COLS), 1.0 / PATCH_COLS, dtype=f.dtype, device=f.device)
    return F.conv2d(F.conv2d(f, rows, groups=c), cols, groups=c)


def context_crops(bev: BEVMap, poses: np.ndarray, margin: int) -> np.ndarray:
    """Patches with ``margin`` cells of context and the observed mask as a 7th channel,
    (N, 7, 22 + 2·margin, 7 + 2·margin) float32, at poses (N, 3) [x m, y m, θ rad]."""
    patches, observed = extract_patches(bev, poses, margin=margin)
    return np.concatenate([patches, observed[:, None].astype(np.float32)], axis=1)


def context_dataset(dataset: PatchDataset, bev: BEVMap, margin: int) -> PatchDataset:
    """The dataset with its patches replaced by :func:`context_crops` of its poses on the
    training world's ``bev`` (the map its patches were cut from): what
    :func:`train_pooled` trains a :class:`PooledNet` on."""
    crops = context_crops(bev, dataset.pose.astype(np.float64), margin)
    arrays = dataset.to_arrays()
    arrays["patches"] = crops
    return PatchDataset.from_arrays(arrays)


def train_pooled(model: PooledNet, crops: PatchDataset, cfg: TrainConfig, *, seed: int = 0,
                 device: str | torch.device | None = None, progress: bool = True) -> TrainResult:
    """Train ``model`` (its normalisation set, :meth:`PooledNet.set_normalization`) on the
    context crops of its vehicles (:func:`context_dataset`) with DGTNet's recipe ``cfg``
    (``profile.train``; ``width``, ``fc_hidden`` and ``conv_taps`` are DGTNet's and not
    used): the masked loss and Adam of :func:`~dgt_lib.learning.training.fit`, the epoch
    ``cfg.selection`` picks, test metrics in the result. ``seed``: batch order and mirror draws."""
    data = TrainingSet.select(crops, model.vehicles, cfg)
    torch.manual_seed(seed)
    return train_network(model, data, cfg, seed=seed, device=device, progress=progress)
