"""Directional costmaps (paper: Costmap Inference).

For each heading θ_k = 2πk/K the BEV is rotated by −θ_k so that θ_k points up
(:func:`dgt_lib.perception.patches.rotate_map`), the network is evaluated on a sliding
window of 22 × 7 patches, the predictions of all patches covering a cell are
averaged, and the result is rotated back onto the world grid:

    C(i, j, θ_k, v) = 1 − L(i, j, θ_k, v)

Two implementations of the same procedure:

* :func:`directional_costmap_reference` — the literal one: every window whose
  centre lies on the map (stride 1), one CNN pass each. Kept as the reference.
* :func:`directional_costmap` — the fast one (the paper names this cost, linear
  in K, as a limitation). It evaluates the network on a sparser lattice of window
  centres (``stride`` = (along the heading, across it) in cells), skips windows
  that cover no observed cell (they can only touch cells whose cost is 1 anyway),
  interpolates the prediction field back onto the stride-1 lattice and then
  averages over covering patches exactly like the reference. Predictions of
  neighbouring windows differ little (the windows overlap by most of their 154
  cells), so interpolation costs little accuracy; the benchmark
  (``benchmarks/bench_costmap.py``) measures speed and the difference.
* :func:`field_costmap` — the same averaging over a whole field of window predictions
  computed at once; :mod:`dgt_lib.beyond.dense` plugs dense networks in here.

All vehicles come from one backbone pass: ``predict`` maps patches (N, 6, 22, 7)
to locomotion (N, V), one column per vehicle head. Unobserved cells cost 1.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
from tqdm.auto import tqdm

from dgt_lib.core.geometry import heading_bins
from dgt_lib.perception.bev import BEVMap
from dgt_lib.perception.patches import (
    PATCH_COLS,
    PATCH_ROWS,
    RotatedMap,
    rotate_map,
    sliding_windows,
    unrotate_map,
    window_counts,
)

Predictor = Callable[[np.ndarray], np.ndarray]
"""patches (N, 6, 22, 7) float32 → locomotion L (N, V) in [0, 1]."""


def _window_lattice(transform, grid, stride: tuple[int, int]):
    """Top-left pixels (a, b) of the windows evaluated in the rotated frame, on a
    lattice of the given stride, restricted to windows centred on the map (with a
    one-stride margin so interpolation between lattice points covers the map)."""
    d = transform.shape[0]
    n_a, n_b = d - PATCH_ROWS + 1, d - PATCH_COLS + 1
    a = np.arange(n_a)
    b = np.arange(n_b)
    # the centre of window (a, b) is rotated pixel (a + 10.5, b + 3)
    ca, cb = np.meshgrid(a + (PATCH_ROWS - 1) / 2, b + (PATCH_COLS - 1) / 2, indexing="ij")
    x, y = transform.rotated_to_xy(ca, cb)
    row, col = grid.xy_to_rc(x, y)
    margin_r, margin_c = stride[0] + 1, stride[1] + 1
    margin = max(margin_r, margin_c)
    inside = ((row > -0.5 - margin) & (row < grid.height - 0.5 + margin)
              & (col > -0.5 - margin) & (col < grid.width - 0.5 + margin))
    on_map = ((row > -0.5) & (row < grid.height - 0.5) & (col > -0.5) & (col < grid.width - 0.5))
    return inside, on_map


def _average_over_covering_windows(pred: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Average, at every rotated pixel, the predictions of all windows covering it.

    pred: (V, n_a, n_b) prediction of the window with top-left (a, b); valid:
    (n_a, n_b) which windows exist. Returns (V, D, D) with NaN where no window covers.
    Summing a window's value over its 22 × 7 footprint is a box filter of the
    prediction field ("full" correlation with a 22 × 7 kernel of ones).
    """
    v, n_a, n_b = pred.shape
    d_rows, d_cols = n_a + PATCH_ROWS - 1, n_b + PATCH_COLS - 1

    def box_sum(field: np.ndarray) -> np.ndarray:
        padded = np.zeros((d_rows + PATCH_ROWS - 1, d_cols + PATCH_COLS - 1), np.float64)
        padded[PATCH_ROWS - 1 : PATCH_ROWS - 1 + n_a, PATCH_COLS - 1 : PATCH_COLS - 1 + n_b] = field
        summed = cv2.boxFilter(padded, -1, (PATCH_COLS, PATCH_ROWS), normalize=False,
                               anchor=(PATCH_COLS - 1, PATCH_ROWS - 1),
                               borderType=cv2.BORDER_CONSTANT)
        return summed[PATCH_ROWS - 1 :, PATCH_COLS - 1 :][:d_rows, :d_cols]

    count = box_sum(valid.astype(np.float64))
    out = np.empty((v, d_rows, d_cols), np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(v):
            out[j] = box_sum(np.where(valid, pred[j], 0.0)) / count
    out[:, count == 0] = np.nan
    return out


def _predict_windows(windows: np.ndarray, a: np.ndarray, b: np.ndarray, predict: Predictor,
                     batch_size: int) -> np.ndarray:
    """Run ``predict`` on windows[:, a_i, b_i] in batches → (N, V)."""
    outs = []
    for start in range(0, len(a), batch_size):
        sl = slice(start, start + batch_size)
        batch = np.ascontiguousarray(np.moveaxis(windows[:, a[sl], b[sl]], 0, 1),
                                     dtype=np.float32)  # (n, 6, 22, 7)
        outs.append(np.asarray(predict(batch), dtype=np.float32))
    if not outs:
        return np.zeros((0, 0), np.float32)
    return np.concatenate(outs)


def _heading_layer(bev: BEVMap, theta: float, predict: Predictor, stride: tuple[int, int],
                   skip_unobserved: bool, batch_size: int) -> np.ndarray:
    """Locomotion (V, H, W) for one heading, by rotate → slide → average → rotate back."""
    return explain_heading_layer(bev, theta, predict, stride=stride,
                                 skip_unobserved=skip_unobserved, batch_size=batch_size)["world"]


def explain_heading_layer(bev: BEVMap, theta: float, predict: Predictor, *,
                          stride: tuple[int, int] = (1, 1), skip_unobserved: bool = False,
                          batch_size: int = 2048) -> dict[str, np.ndarray]:
    """One heading of the costmap procedure, with every intermediate (for teaching).

    Returns a dict: ``rotated`` (6, D, D) the BEV rotated so θ points up;
    ``evaluated`` (n_a, n_b) bool, the windows the network saw (indexed by their
    top-left pixel); ``field`` (V, n_a, n_b) the prediction of each window (after
    interpolation from the lattice when ``stride`` > 1); ``averaged`` (V, D, D)
    the mean over all windows covering each rotated pixel (NaN where none does);
    ``world`` (V, H, W) locomotion L rotated back onto the BEV grid; and
    ``transform``, the :class:`~dgt_lib.perception.patches.RotationTransform`.
    """
    rotated = rotate_map(bev, theta)
    windows = sliding_windows(rotated.channels)  # (6, n_a, n_b, 22, 7) view
    n_a, n_b = windows.shape[1:3]
    inside, on_map = _window_lattice(rotated.transform, bev.grid, stride)
    lattice = np.zeros((n_a, n_b), bool)
    lattice[:: stride[0], :: stride[1]] = True
    evaluate = lattice & inside if stride != (1, 1) else on_map.copy()
    if skip_unobserved:
        evaluate &= window_counts(rotated.observed) > 0  # covers an observed pixel
    a, b = np.nonzero(evaluate)
    pred_points = _predict_windows(windows, a, b, predict, batch_size)  # (N, V)
    n_v = pred_points.shape[1] if len(pred_points) else 1
    if stride == (1, 1):
        field = np.zeros((n_v, n_a, n_b), np.float32)
        field[:, a, b] = pred_points.T
        valid = evaluate
    else:
        field, valid = _interpolate_lattice(pred_points, a, b, stride, (n_a, n_b), on_map)
    averaged = _average_over_covering_windows(field, valid)  # (V, D, D)
    world = unrotate_map(np.nan_to_num(averaged, nan=0.0), rotated.transform)
    return {"rotated": rotated.channels, "evaluated": evaluate, "field": field,
            "averaged": averaged, "world": world, "transform": rotated.transform}


def _interpolate_lattice(values: np.ndarray, a: np.ndarray, b: np.ndarray,
                         stride: tuple[int, int], shape: tuple[int, int], on_map: np.ndarray):
    """Bilinearly interpolate predictions known on the stride lattice onto every
    window position that is centred on the map. Lattice points that were skipped
    (covering no observed cell) take the value of their nearest evaluated
    neighbours (normalised convolution), which only affects unobserved cells."""
    coarse, weight = lattice_arrays(values, a, b, stride, shape)
    filled, filled_w = fill_lattice(coarse, weight)
    field, known = lattice_to_windows(filled, filled_w, stride, slice(0, shape[0]),
                                      slice(0, shape[1]))
    return field, on_map & known


def lattice_arrays(values: np.ndarray, a: np.ndarray, b: np.ndarray, stride: tuple[int, int],
                   shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The predictions (N, V) of the evaluated windows with top-left (a, b) on the coarse
    lattice: values (V, ⌈n_a/s_a⌉, ⌈n_b/s_b⌉) float32 (0 where not evaluated) and weight
    (same shape without V) 1 where evaluated, for window positions of ``shape`` (n_a, n_b)."""
    n_v = values.shape[1]
    la, lb = -(-shape[0] // stride[0]), -(-shape[1] // stride[1])
    coarse = np.zeros((n_v, la, lb), np.float32)
    weight = np.zeros((la, lb), np.float32)
    coarse[:, a // stride[0], b // stride[1]] = values.T
    weight[a // stride[0], b // stride[1]] = 1.0
    return coarse, weight


LATTICE_FILL_STEPS = 3
"""Normalised 3 × 3 blurs that fill skipped lattice points: a filled value depends on
evaluated points up to this many lattice steps away."""


def fill_lattice(coarse: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fill skipped lattice points (weight 0) from evaluated neighbours by a normalised
    3 × 3 blur, :data:`LATTICE_FILL_STEPS` times. Returns (filled (V, la, lb), weight
    (la, lb): 1 where a value is known)."""
    n_v = coarse.shape[0]
    filled_w = weight.copy()
    filled = coarse.copy()
    for _ in range(LATTICE_FILL_STEPS):
        missing = filled_w == 0
        if not missing.any():
            break
        w_blur = cv2.blur(filled_w, (3, 3), borderType=cv2.BORDER_CONSTANT)
        for j in range(n_v):
            v_blur = cv2.blur(filled[j] * filled_w, (3, 3), borderType=cv2.BORDER_CONSTANT)
            filled[j] = np.where(missing & (w_blur > 0), v_blur / np.maximum(w_blur, 1e-9),
                                 filled[j])
        filled_w = np.where(missing & (w_blur > 0), 1.0, filled_w).astype(np.float32)
    return filled, filled_w


def lattice_to_windows(filled: np.ndarray, filled_w: np.ndarray, stride: tuple[int, int],
                       rows: slice, cols: slice) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear interpolation of the filled lattice at the window positions
    ``[rows, cols]`` (unit-step slices of top-left pixels): fine position p lies at coarse
    coordinate p / stride. Returns field (V, r, c) and known (r, c) bool (every
    interpolation weight on a known lattice point); a part equals the part of the whole."""
    r_idx = (np.arange(rows.start, rows.stop) / stride[0]).astype(np.float32)
    c_idx = (np.arange(cols.start, cols.stop) / stride[1]).astype(np.float32)
    map_c, map_r = np.meshgrid(c_idx, r_idx)
    field = np.stack([cv2.remap(filled[j], map_c, map_r, cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_REPLICATE)
                      for j in range(filled.shape[0])])
    known = cv2.remap(filled_w, map_c, map_r, cv2.INTER_LINEAR,
                      borderMode=cv2.BORDER_CONSTANT) > 0.999
    return field, known


def _costmap(bev: BEVMap, heading_layer: Callable[[float], np.ndarray], n_headings: int,
             progress: bool) -> np.ndarray:
    """Cost (V, K, H, W) from ``heading_layer(θ)`` → locomotion (V, H, W) per heading."""
    thetas = heading_bins(n_headings)
    layers = [heading_layer(float(theta))
              for theta in tqdm(thetas, desc="headings", unit="θ", disable=not progress,
                                leave=False)]
    locomotion = np.stack(layers, axis=1)  # (V, K, H, W)
    cost = 1.0 - np.clip(locomotion, 0.0, 1.0)
    cost[:, :, ~bev.observed] = 1.0
    return cost.astype(np.float32)


def _window_costmap(bev: BEVMap, predict: Predictor, n_headings: int, stride: tuple[int, int],
                    skip_unobserved: bool, batch_size: int, progress: bool) -> np.ndarray:
    return _costmap(bev, lambda theta: _heading_layer(bev, theta, predict, stride,
                                                      skip_unobserved, batch_size),
                    n_headings, progress)


def directional_costmap_reference(bev: BEVMap, predict: Predictor, n_headings: int = 8, *,
                                  batch_size: int = 2048, progress: bool = True) -> np.ndarray:
    """The paper's procedure, literally: every window centred on the map, stride 1.

    Returns cost (V, K, H, W) float32 in [0, 1]: C = 1 − L, layer k = heading
    θ_k = 2πk/K (k = 0 is +x, counter-clockwise), 1 on unobserved cells.
    """
    return _window_costmap(bev, predict, n_headings, (1, 1), False, batch_size, progress)


def directional_costmap(bev: BEVMap, predict: Predictor, n_headings: int = 8, *,
                        stride: tuple[int, int] = (4, 2), skip_unobserved: bool = True,
                        batch_size: int = 2048, progress: bool = True) -> np.ndarray:
    """The fast directional costmap (same output as the reference, see module docstring).

    stride: (along the heading, across it) [cells] between evaluated window
    centres; (1, 1) with ``skip_unobserved=False`` is exactly the reference.
    """
    stride = (int(stride[0]), int(stride[1]))
    if min(stride) < 1:
        raise ValueError(f"stride must be ≥ 1 cell, got {stride}")
    return _window_costmap(bev, predict, n_headings, stride, skip_unobserved, batch_size,
                           progress)


WindowField = Callable[[RotatedMap, np.ndarray], np.ndarray]
"""(rotated map, windows (n_a, n_b) bool centred on the map) → L̂ (V, n_a, n_b) of the
windows, indexed by their top-left pixel as :func:`sliding_windows`."""


def field_heading_layer(bev: BEVMap, theta: float, window_field: WindowField) -> np.ndarray:
    """Locomotion (V, H, W) for one heading from a whole field of window predictions:
    rotate → ``window_field`` → average over covering windows → rotate back."""
    rotated = rotate_map(bev, theta)
    _, on_map = _window_lattice(rotated.transform, bev.grid, (1, 1))
    averaged = _average_over_covering_windows(window_field(rotated, on_map), on_map)
    return unrotate_map(np.nan_to_num(averaged, nan=0.0), rotated.transform)


def field_costmap(bev: BEVMap, window_field: WindowField, n_headings: int = 8, *,
                  progress: bool = True) -> np.ndarray:
    """Cost (V, K, H, W) from a provider of whole window fields: for each heading rotate →
    ``window_field`` → average over covering windows → rotate back. The plug-in point for
    networks evaluated densely (:mod:`dgt_lib.beyond.dense`); same layout as the
    reference."""
    return _costmap(bev, lambda theta: field_heading_layer(bev, theta, window_field),
                    n_headings, progress)
