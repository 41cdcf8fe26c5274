"""Dense evaluation of :class:`~dgt_lib.learning.model.DGTNet` over a whole rotated map.

The literal costmap runs the network once per 22 × 7 window. Here each ResNet-18
branch runs once over the whole (6, D, D) rotated map, fully convolutionally; its
layer-4 feature map (stride 32) stands for the window centred on each of its cells,
the fully connected layer and the vehicle heads run as 1 × 1 operations on it, and
the prediction of every window (top-left (a, b), centre (a + 10.5, b + 3)) is read
off that field by bilinear interpolation::

    rotated map (6, D, D) ─ centre H̄ (22 × 7 box mean) ─ normalise ─┬─ RGB trunk ─┐
                                                                    └─ H trunk ───┴─ concat
      (16·width, D/32, D/32) ── FC as 1×1 ── heads as 1×1 ── sigmoid ── bilinear at window centres

This is *not* the per-window network: on a 22 × 7 window every layer of the
branch is dominated by zero padding (layer 4 is 1 × 1), whereas a dense layer-4
cell sees ~435 px of real terrain around it, far beyond its window. The two agree
exactly only when the map is a single window with flat H̄ (the test); on real maps
``benchmarks/bench_costmap.py`` measures the difference.
"""

from __future__ import annotations

import cv2
import numpy as np
import torch

from dgt_lib.beyond.pooled import PooledNet
from dgt_lib.learning.model import HEIGHT_CHANNELS, RGB_CHANNELS, DGTNet
from dgt_lib.mapping.costmap import field_costmap
from dgt_lib.perception.bev import BEVMap
from dgt_lib.perception.patches import PATCH_COLS, PATCH_ROWS, RotatedMap

TRUNK_STRIDE = 32
"""Pixels of the input per cell of a ResNet-18's layer-4 feature map."""


def local_height_mean(heights: np.ndarray) -> np.ndarray:
    """Mean H̄ [m] of the finite cells in the 22 × 7 box centred on each pixel, (D, D)
    → (D, D) float32 (0 where the box has none): the dense stand-in for the per-patch
    mean that :func:`~dgt_lib.learning.model.centre_heights` subtracts."""
    finite = np.isfinite(heights)
    size = (PATCH_COLS, PATCH_ROWS)
    total = cv2.boxFilter(np.where(finite, heights, 0.0).astype(np.float64), -1, size,
                          normalize=False, borderType=cv2.BORDER_CONSTANT)
    count = cv2.boxFilter(finite.astype(np.float64), -1, size, normalize=False,
                          borderType=cv2.BORDER_CONSTANT)
    return (total / np.maximum(count, 1.0)).astype(np.float32)


@torch.no_grad()
def dense_locomotion(model: DGTNet, channels: np.ndarray) -> np.ndarray:
    """L̂ on the layer-4 grid: raw rotated channels (6, D, D) → (V, ⌈D/32⌉, ⌈D/32⌉) in [0, 1].

    Cell (p, q) of the result is centred on input pixel (32 p, 32 q).
    """
    model.eval()
    x = np.array(channels, dtype=np.float32)
    x[HEIGHT_CHANNELS.start] -= local_height_mean(x[HEIGHT_CHANNELS.start])
    device = model.input_mean.device
    t = torch.from_numpy(x).to(device)[None]
    t = (t - model.input_mean[:, None, None]) / model.input_std[:, None, None]
    t = torch.nan_to_num(t, nan=0.0, posinf=0.0, neginf=0.0)
    features = torch.cat([model.rgb.feature_map(t[:, RGB_CHANNELS]),
                          model.height.feature_map(t[:, HEIGHT_CHANNELS])], dim=1)[0]
    fc = model.fc[0]
    z = torch.relu(torch.einsum("chw,oc->ohw", features, fc.weight) + fc.bias[:, None, None])
    weight = torch.cat([head.weight for head in model.vehicle_heads])  # (V, fc_hidden)
    bias = torch.cat([head.bias for head in model.vehicle_heads])
    logits = torch.einsum("chw,vc->vhw", z, weight) + bias[:, None, None]
    return torch.sigmoid(logits).cpu().numpy().astype(np.float32)


def dense_window_field(model: DGTNet, channels: np.ndarray) -> np.ndarray:
    """L̂ of every 22 × 7 window of a rotated map, by dense evaluation:
    (6, D, D) → (V, D − 21, D − 6), element [:, a, b] for the window with top-left (a, b)
    (the indexing of :func:`~dgt_lib.perception.patches.sliding_windows`)."""
    coarse = dense_locomotion(model, channels)
    d_rows, d_cols = channels.shape[1:]
    rows = ((np.arange(d_rows - PATCH_ROWS + 1) + (PATCH_ROWS - 1) / 2) / TRUNK_STRIDE)
    cols = ((np.arange(d_cols - PATCH_COLS + 1) + (PATCH_COLS - 1) / 2) / TRUNK_STRIDE)
    map_c, map_r = np.meshgrid(cols.astype(np.float32), rows.astype(np.float32))
    return np.stack([cv2.remap(layer, map_c, map_r, cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE) for layer in coarse])


def directional_costmap_dense(bev: BEVMap, model: DGTNet | PooledNet, n_headings: int = 8, *,
                              literal: bool = False, progress: bool = True) -> np.ndarray:
    """The directional costmap (V, K, H, W) with every window's prediction from one dense
    pass per heading; same layout as :func:`dgt_lib.mapping.costmap.directional_costmap`.

    A :class:`~dgt_lib.beyond.pooled.PooledNet` is evaluated exactly
    (:meth:`~dgt_lib.beyond.pooled.PooledNet.window_field`); ``literal=True`` runs each of
    its windows on its own instead (the reference the dense pass equals). A DGTNet is
    evaluated by :func:`dense_window_field`, which is not the per-window network (a
    measured negative result)."""
    if isinstance(model, PooledNet):
        def field(rotated: RotatedMap, on_map: np.ndarray) -> np.ndarray:
            if literal:
                return model.literal_window_field(rotated.channels, rotated.observed, on_map)
            return model.window_field(rotated.channels, rotated.observed, on_map)
    elif literal:
        raise ValueError("literal=True needs a PooledNet; a DGTNet's literal procedure is "
                         "directional_costmap_reference")
    else:
        def field(rotated: RotatedMap, on_map: np.ndarray) -> np.ndarray:
            return dense_window_field(model, rotated.channels)
    return field_costmap(bev, field, n_headings, progress=progress)
