"""Directional costmaps that update while the map grows (the paper's Limitations & Future
Work name incremental updates as future work; this is ours).

A vehicle exploring an unknown world adds one RGB-D frame at a time to its BEV map; a
frame changes a few thousand cells. :class:`IncrementalCostmap` keeps the K heading
layers of :func:`~dgt_lib.mapping.costmap.directional_costmap` (the lattice fast path,
``skip_unobserved=True``) and, given the BEV cells that changed (a mask, or a box),
recomputes only what depends on them, heading by heading. In the frame rotated by −θ_k
(θ_k up):

1. rotated pixels whose bilinear support touches a changed cell are resampled;
2. lattice windows (window centres every ``stride`` cells) whose 22 × 7 footprint holds
   such a pixel are evaluated by the network again — the only costly step;
3. the lattice is filled and interpolated again (cheap, whole lattice), and the window
   positions whose interpolated prediction changed are found by comparison;
4. the average over covering windows,

       L(p, θ_k) = Σ_{w ∋ p} L̂_w / |{w ∋ p}|,   C(i, j, θ_k) = 1 − L(i, j, θ_k),

   is recomputed on the rotated pixels those windows cover (22 × 7 further), and
5. rotated back onto the BEV cells that read those pixels.

Every step reads the same arrays as a full recompute and works on exactly the pixels,
windows and cells that can change, so the layers equal ``directional_costmap`` of the
same map (to float rounding of the box sums; ``tests/test_incremental.py``).

:class:`DenseIncrementalCostmap` does the same for a
:class:`~dgt_lib.beyond.pooled.PooledNet` without a lattice: step 2 is one dense pass of
the network over the windows whose context reads a changed pixel, and its layers equal
``directional_costmap_dense`` of the same map (``tests/test_pooled.py``).
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass

import cv2
import numpy as np

from dgt_lib.core.geometry import heading_bins
from dgt_lib.mapping.costmap import (
    Predictor,
    _average_over_covering_windows,
    _window_lattice,
    fill_lattice,
    lattice_to_windows,
)
from dgt_lib.perception.bev import N_CHANNELS, BEVMap, changed_mask
from dgt_lib.perception.patches import (
    PATCH_COLS,
    PATCH_ROWS,
    RotationTransform,
    rotated_pixels,
    rotation_transform,
    sliding_windows,
    unrotate_map,
    window_counts,
)

Box = tuple[slice, slice]
"""(rows, cols) unit-step slices of a rectangle of cells or pixels."""

_SUPPORT_MARGIN = 0.5
"""Slack [cells] around a bilinear support (cv2 rounds coordinates to 1/32 cell)."""


def changed_cells(old: BEVMap | None, new: BEVMap) -> Box | None:
    """The bounding box of :func:`changed_mask`, or None when nothing changed."""
    mask = changed_mask(old, new)
    return None if mask is None else _bbox(mask)


def _bbox(mask: np.ndarray, offset: tuple[int, int] = (0, 0)) -> Box | None:
    """Bounding box of the True cells of a 2-D mask (shifted by ``offset``), or None."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not len(rows):
        return None
    return (slice(int(rows[0]) + offset[0], int(rows[-1]) + 1 + offset[0]),
            slice(int(cols[0]) + offset[1], int(cols[-1]) + 1 + offset[1]))


def _clip(box: Box, shape: tuple[int, int]) -> Box | None:
    r0, r1 = max(box[0].start, 0), min(box[0].stop, shape[0])
    c0, c1 = max(box[1].start, 0), min(box[1].stop, shape[1])
    return (slice(r0, r1), slice(c0, c1)) if r1 > r0 and c1 > c0 else None


def _touching(row: np.ndarray, col: np.ndarray, box: Box,
              near: np.ndarray | None = None) -> np.ndarray:
    """Which continuous positions (row, col) (integers at pixel centres) have a bilinear
    support — pixels ⌊·⌋ and ⌊·⌋ + 1 — inside ``box`` and, when ``near`` is given, at a
    cell of the changed mask: ``near`` is that mask dilated by ``_NEAR_RADIUS`` cells, read
    at the nearest cell (every support cell is within 1 + the margin of it)."""
    m = _SUPPORT_MARGIN
    inside = ((row > box[0].start - 1 - m) & (row < box[0].stop + m)
              & (col > box[1].start - 1 - m) & (col < box[1].stop + m))
    if near is not None and inside.any():
        h, w = near.shape
        r = np.clip(np.rint(row[inside]).astype(np.intp), 0, h - 1)
        c = np.clip(np.rint(col[inside]).astype(np.intp), 0, w - 1)
        inside[inside] = near[r, c]
    return inside


_NEAR_RADIUS = 2
"""Cells: a bilinear support lies within ⌈0.5 + 1 + _SUPPORT_MARGIN⌉ of the nearest cell."""


def _dilate(mask: np.ndarray, radius: int) -> np.ndarray:
    size = 2 * radius + 1
    return cv2.dilate(mask.astype(np.uint8), np.ones((size, size), np.uint8)).astype(bool)


def _reaverage(grid, layer, win: Box) -> Box | None:
    """Steps 4–5 after the window predictions ``layer.field[:, win]`` changed: the mean over
    covering windows on the rotated pixels those windows cover, then the BEV cells that
    read those pixels, rotated back into ``layer.world``. Returns that box of cells (or
    None). ``layer`` has ``field``, ``valid``, ``averaged``, ``world`` and ``transform``."""
    n_a, n_b = layer.valid.shape
    d = layer.averaged.shape[-1]
    pix = (slice(win[0].start, win[0].stop + PATCH_ROWS - 1),
           slice(win[1].start, win[1].stop + PATCH_COLS - 1))
    src = (slice(max(pix[0].start - PATCH_ROWS + 1, 0), min(pix[0].stop, n_a)),
           slice(max(pix[1].start - PATCH_COLS + 1, 0), min(pix[1].stop, n_b)))
    averaged = _average_over_covering_windows(layer.field[(slice(None), *src)],
                                              layer.valid[src])
    sub = (slice(None), slice(pix[0].start - src[0].start, pix[0].stop - src[0].start),
           slice(pix[1].start - src[1].start, pix[1].stop - src[1].start))
    layer.averaged[(slice(None), *pix)] = np.nan_to_num(averaged[sub], nan=0.0)
    # BEV cells that read those pixels
    pix = _clip(pix, (d, d))
    rows, cols = grid.xy_to_rc(*layer.transform.rotated_to_xy(
        np.array([pix[0].start - 1, pix[0].start - 1, pix[0].stop, pix[0].stop]),
        np.array([pix[1].start - 1, pix[1].stop, pix[1].start - 1, pix[1].stop])))
    cells = _clip((slice(int(np.floor(rows.min())) - 1, int(np.ceil(rows.max())) + 2),
                   slice(int(np.floor(cols.min())) - 1, int(np.ceil(cols.max())) + 2)),
                  grid.shape)
    if cells is None:
        return None
    layer.world[(slice(None), *cells)] = unrotate_map(layer.averaged, layer.transform,
                                                      cells=cells)
    return cells


@dataclass
class _HeadingLayer:
    """Everything one heading keeps between updates (rotated frame of θ_k)."""

    transform: RotationTransform
    bev_row: np.ndarray  # (D, D) float32 BEV row of each rotated pixel
    bev_col: np.ndarray  # (D, D) float32 BEV column of each rotated pixel
    inside: np.ndarray  # (n_a, n_b) bool, windows the lattice may evaluate
    on_map: np.ndarray  # (n_a, n_b) bool, windows centred on the map
    channels: np.ndarray  # (6, D, D) the rotated BEV
    observed: np.ndarray  # (D, D) bool
    coarse: np.ndarray  # (V, la, lb) raw lattice predictions (0 where not evaluated)
    weight: np.ndarray  # (la, lb) 1 where evaluated
    filled: np.ndarray  # (V, la, lb) after fill_lattice
    filled_w: np.ndarray  # (la, lb)
    field: np.ndarray  # (V, n_a, n_b) interpolated window predictions
    valid: np.ndarray  # (n_a, n_b) bool
    averaged: np.ndarray  # (V, D, D) mean over covering windows, 0 where none
    world: np.ndarray  # (V, H, W) locomotion L back on the BEV grid


@dataclass
class UpdateStats:
    """What one :meth:`IncrementalCostmap.update` recomputed: windows evaluated by the
    network (all headings), BEV cells rewritten (summed over headings), and the wall and
    CPU time [s] of the update."""

    windows: int = 0
    cells: int = 0
    wall_s: float = 0.0
    cpu_s: float = 0.0


class _GrowingCostmap(ABC):
    """What every incremental costmap shares: the cost layers, the map they were last
    brought up to date with, :meth:`refresh` (finds the changed cells itself) and the
    conversion C = 1 − L. Subclasses keep the heading layers (``_layers``, each with a
    ``world`` (V, H, W) locomotion) and implement :meth:`update`."""

    _layers: list

    def __init__(self, grid, n_vehicles: int, n_headings: int, tolerance: float) -> None:
        if tolerance < 0:
            raise ValueError(f"tolerance must be ≥ 0, got {tolerance}")
        self.grid = grid
        self.n_vehicles, self.n_headings = int(n_vehicles), int(n_headings)
        self.tolerance = float(tolerance)
        self.observed = np.zeros(grid.shape, bool)
        # the BEV as :meth:`refresh` last passed it on, cell by cell
        self._basis = np.zeros((N_CHANNELS, *grid.shape), np.float32)
        self._cost = np.ones((self.n_vehicles, self.n_headings, *grid.shape), np.float32)

    @property
    def cost(self) -> np.ndarray:
        """Cost (V, K, H, W) float32 in [0, 1]: C = 1 − L, 1 on unobserved cells (a view:
        copy it to keep a snapshot)."""
        return self._cost

    def refresh(self, bev: BEVMap) -> UpdateStats:
        """Bring the layers up to date with ``bev``, finding what changed by itself: the
        cells whose observed flag changed or one of whose channels moved by more than
        ``tolerance`` (channel units: RGB 0..1, H̄ and σ_H [m], ‖∇H̄‖ [m/m]) since this
        method last passed the cell on to :meth:`update`.

        ``tolerance = 0`` is exact (the layers equal the full costmap of ``bev``). A
        re-observed cell's mean height moves by millimetres from frame to frame, so most
        of a frame's cells change a little; with ``tolerance > 0`` only the new and the
        clearly changed ones are evaluated again, and every cell the network last read is
        within 2 × tolerance of ``bev`` (what :meth:`update` resamples around a changed
        cell is read from ``bev``, so a skipped cell may be one step newer than its basis).
        """
        if bev.grid != self.grid:
            raise ValueError(f"BEV grid {bev.grid} is not the costmap's {self.grid}")
        moved = np.abs(bev.channels - self._basis).max(axis=0) > self.tolerance
        changed = moved | (bev.observed != self.observed)
        self._basis[:, changed] = bev.channels[:, changed]
        return self.update(bev, changed if changed.any() else None)

    def update(self, bev: BEVMap, changed: np.ndarray | Box | None) -> UpdateStats:
        """Bring the layers up to date with ``bev``, whose cells outside ``changed`` equal
        the previous map's: an (H, W) bool mask (:func:`changed_mask`; only windows that
        read a changed cell are evaluated again) or a box of (rows, cols) slices
        (:func:`changed_cells`; every window reading the box), None when nothing changed.
        ``stats.windows`` counts the windows the network evaluated again (all headings)."""
        wall0, cpu0 = time.perf_counter(), time.process_time()
        stats = UpdateStats()
        changed, near = self._changed_box(bev, changed)
        if changed is not None:
            for k, cells in self._update_layers(bev, changed, near, stats):
                stats.cells += (cells[0].stop - cells[0].start) * (cells[1].stop
                                                                   - cells[1].start)
                self._write_cost(k, cells, bev)
            self._write_cost(None, changed, bev)
            self.observed[changed] = bev.observed[changed]
        stats.wall_s = time.perf_counter() - wall0
        stats.cpu_s = time.process_time() - cpu0
        return stats

    @abstractmethod
    def _update_layers(self, bev: BEVMap, changed: Box, near: np.ndarray | None,
                       stats: UpdateStats) -> list[tuple[int, Box]]:
        """Bring every heading layer's ``world`` up to date with ``bev`` around ``changed``
        (``near``: the dilated changed mask, or None); count the windows evaluated in
        ``stats``; return (heading, box of BEV cells rewritten) pairs."""

    def _changed_box(self, bev: BEVMap, changed: np.ndarray | Box | None
                     ) -> tuple[Box | None, np.ndarray | None]:
        """The box of ``changed`` (a mask or a box) clipped to the grid, and the mask dilated
        by ``_NEAR_RADIUS`` (None for a box), after checking ``bev``'s grid."""
        if bev.grid != self.grid:
            raise ValueError(f"BEV grid {bev.grid} is not the costmap's {self.grid}")
        near = None
        if isinstance(changed, np.ndarray):
            if changed.shape != self.grid.shape:
                raise ValueError(f"changed mask {changed.shape} ≠ grid {self.grid.shape}")
            box = _bbox(changed)
            near = None if box is None else _dilate(changed, _NEAR_RADIUS)
            changed = box
        return (None if changed is None else _clip(changed, self.grid.shape)), near

    def _write_cost(self, k: int | None, cells: Box, bev: BEVMap) -> None:
        """C = 1 − clip(L, 0, 1) on ``cells`` of heading k (all headings when None),
        1 where unobserved."""
        ks = range(self.n_headings) if k is None else (k,)
        observed = bev.observed[cells]
        for j in ks:
            cost = 1.0 - np.clip(self._layers[j].world[(slice(None), *cells)], 0.0, 1.0)
            cost[:, ~observed] = 1.0
            self._cost[(slice(None), j, *cells)] = cost


class IncrementalCostmap(_GrowingCostmap):
    """K directional heading layers of a growing BEV map, updated where it changed.

    Equal to ``directional_costmap(bev, predict, n_headings, stride=stride,
    skip_unobserved=True)`` of the latest map passed to :meth:`update`. Starts from an
    empty map (every cell unobserved: cost 1). ``predict`` maps patches (N, 6, 22, 7) to
    locomotion (N, V); give it one column for one vehicle (fastest).
    """

    def __init__(self, grid, predict: Predictor, n_vehicles: int, n_headings: int = 8, *,
                 stride: tuple[int, int] = (6, 3), batch_size: int = 2048,
                 tolerance: float = 0.0):
        self.stride = (int(stride[0]), int(stride[1]))
        if self.stride == (1, 1) or min(self.stride) < 1:
            raise ValueError(f"the incremental costmap follows the lattice path: stride "
                             f"must be ≥ 1 and not (1, 1), got {stride}")
        super().__init__(grid, n_vehicles, n_headings, tolerance)
        self.predict, self.batch_size = predict, batch_size
        self._layers = [self._empty_layer(float(t)) for t in heading_bins(self.n_headings)]

    def _empty_layer(self, theta: float) -> _HeadingLayer:
        transform = rotation_transform(self.grid, theta)
        d = transform.shape[0]
        rows, cols = np.mgrid[0:d, 0:d]
        bev_row, bev_col = self.grid.xy_to_rc(*transform.rotated_to_xy(rows, cols))
        inside, on_map = _window_lattice(transform, self.grid, self.stride)
        n_a, n_b = inside.shape
        la, lb = -(-n_a // self.stride[0]), -(-n_b // self.stride[1])
        v, (h, w) = self.n_vehicles, self.grid.shape
        return _HeadingLayer(
            transform, bev_row.astype(np.float32), bev_col.astype(np.float32), inside,
            on_map, np.zeros((N_CHANNELS, d, d), np.float32), np.zeros((d, d), bool),
            np.zeros((v, la, lb), np.float32), np.zeros((la, lb), np.float32),
            np.zeros((v, la, lb), np.float32), np.zeros((la, lb), np.float32),
            np.zeros((v, n_a, n_b), np.float32), np.zeros((n_a, n_b), bool),
            np.zeros((v, d, d), np.float32), np.zeros((v, h, w), np.float32))

    def _update_layers(self, bev: BEVMap, changed: Box, near: np.ndarray | None,
                       stats: UpdateStats) -> list[tuple[int, Box]]:
        # 1–2: resample touched pixels, find the lattice windows that read them
        todo = [self._resample(layer, bev, changed, near) for layer in self._layers]
        patches = [sliding_windows(layer.channels)[:, a, b] for layer, (a, b, _) in
                   zip(self._layers, todo, strict=True)]
        n = [len(a) for a, _, _ in todo]
        stats.windows = int(sum(n))
        pred = (self._predict(np.concatenate([np.moveaxis(p, 0, 1) for p in patches]))
                if stats.windows else np.zeros((0, self.n_vehicles), np.float32))
        splits = np.split(pred, np.cumsum(n)[:-1])
        # 3–5: lattice, interpolation, averaging and rotation back, where they change
        out = []
        for k, (layer, (a, b, dirty), p) in enumerate(zip(self._layers, todo, splits,
                                                          strict=True)):
            cells = self._refresh(layer, a, b, dirty, p)
            if cells is not None:
                out.append((k, cells))
        return out

    def _predict(self, patches: np.ndarray) -> np.ndarray:
        outs = [np.asarray(self.predict(np.ascontiguousarray(patches[i:i + self.batch_size],
                                                             dtype=np.float32)), np.float32)
                for i in range(0, len(patches), self.batch_size)]
        return np.concatenate(outs).reshape(len(patches), self.n_vehicles)

    def _resample(self, layer: _HeadingLayer, bev: BEVMap, changed: Box,
                  near: np.ndarray | None):
        """Step 1–2 for one heading: resample the rotated pixels touching ``changed`` (and
        ``near``, the dilated changed mask, if given) and return the lattice windows to
        evaluate (top-left rows a, cols b) and the mask of lattice windows whose content
        changed (n_a, n_b)."""
        touched = _touching(layer.bev_row, layer.bev_col, changed, near)
        box = _bbox(touched)
        dirty = np.zeros(layer.inside.shape, bool)
        if box is None:
            return np.zeros(0, int), np.zeros(0, int), dirty
        # (untouched pixels of the box resample to what they were)
        layer.channels[(slice(None), *box)], layer.observed[box] = rotated_pixels(
            bev, layer.transform, *box)
        # windows whose footprint holds a touched pixel, on the lattice
        s0, s1 = self.stride
        w_box = _clip((slice(box[0].start - PATCH_ROWS + 1, box[0].stop),
                       slice(box[1].start - PATCH_COLS + 1, box[1].stop)), dirty.shape)
        pix = (slice(w_box[0].start, w_box[0].stop + PATCH_ROWS - 1),
               slice(w_box[1].start, w_box[1].stop + PATCH_COLS - 1))
        dirty[w_box] = window_counts(touched[pix]) > 0
        lattice = np.zeros_like(dirty)
        lattice[::s0, ::s1] = True
        dirty &= lattice
        covers = np.zeros_like(dirty)
        covers[w_box] = window_counts(layer.observed[pix]) > 0
        a, b = np.nonzero(dirty & layer.inside & covers)
        return a, b, dirty

    def _refresh(self, layer: _HeadingLayer, a: np.ndarray, b: np.ndarray,
                 dirty: np.ndarray, pred: np.ndarray) -> Box | None:
        """Steps 3–5 for one heading; returns the box of BEV cells rewritten (or None)."""
        s0, s1 = self.stride
        da, db = np.nonzero(dirty)
        layer.coarse[:, da // s0, db // s1] = 0.0
        layer.weight[da // s0, db // s1] = 0.0
        layer.coarse[:, a // s0, b // s1] = pred.T
        layer.weight[a // s0, b // s1] = 1.0
        filled, filled_w = fill_lattice(layer.coarse, layer.weight)
        moved = _bbox(np.any(filled != layer.filled, axis=0) | (filled_w != layer.filled_w))
        layer.filled, layer.filled_w = filled, filled_w
        if moved is None:
            return None
        # window positions interpolated from a moved lattice point: p / s ∈ (c − 1, c + 1)
        n_a, n_b = layer.valid.shape
        win = _clip((slice((moved[0].start - 1) * s0, moved[0].stop * s0 + 1),
                     slice((moved[1].start - 1) * s1, moved[1].stop * s1 + 1)), (n_a, n_b))
        field, known = lattice_to_windows(filled, filled_w, self.stride, *win)
        layer.field[(slice(None), *win)] = field
        layer.valid[win] = layer.on_map[win] & known
        return _reaverage(self.grid, layer, win)


@dataclass
class _DenseLayer:
    """What one heading keeps for :class:`DenseIncrementalCostmap` (rotated frame of θ_k)."""

    transform: RotationTransform
    bev_row: np.ndarray  # (D, D) float32 BEV row of each rotated pixel
    bev_col: np.ndarray  # (D, D) float32 BEV column of each rotated pixel
    valid: np.ndarray  # (n_a, n_b) bool, windows centred on the map
    padded: np.ndarray  # (7, D + 2m, D + 2m) the rotated BEV and observed, with its margin
    field: np.ndarray  # (V, n_a, n_b) window predictions
    averaged: np.ndarray  # (V, D, D) mean over covering windows, 0 where none
    world: np.ndarray  # (V, H, W) locomotion L back on the BEV grid


class DenseIncrementalCostmap(_GrowingCostmap):
    """:class:`IncrementalCostmap` for a :class:`~dgt_lib.beyond.pooled.PooledNet`: equal to
    ``directional_costmap_dense(bev, model, n_headings)`` of the latest map (exact, every
    window, no lattice). After a change, each heading resamples the rotated pixels that read
    a changed cell and runs the network densely over just the windows whose context (the
    22 × 7 footprint and ``model.margin`` cells around it) holds one of them — one trunk
    pass over a small region — then averages and rotates back where that changed anything.
    ``vehicles``: the heads to keep, one cost layer each (default all of the model's).
    """

    def __init__(self, grid, model, n_headings: int = 8, *,
                 vehicles: tuple[str, ...] | None = None, tolerance: float = 0.0) -> None:
        vehicles = tuple(model.vehicles) if vehicles is None else tuple(vehicles)
        super().__init__(grid, len(vehicles), n_headings, tolerance)
        self.model = model
        self._heads = [model.head_index(v) for v in vehicles]  # cost layer j = head _heads[j]
        empty = model.empty_window()[self._heads]  # what a window seeing nothing predicts
        self._layers = [self._empty_layer(float(t), empty) for t in heading_bins(n_headings)]

    def _empty_layer(self, theta: float, empty: np.ndarray) -> _DenseLayer:
        transform = rotation_transform(self.grid, theta)
        d, m = transform.shape[0], self.model.margin
        rows, cols = np.mgrid[0:d, 0:d]
        bev_row, bev_col = self.grid.xy_to_rc(*transform.rotated_to_xy(rows, cols))
        _, on_map = _window_lattice(transform, self.grid, (1, 1))
        field = np.where(on_map, empty[:, None, None], 0.0).astype(np.float32)
        averaged = np.nan_to_num(_average_over_covering_windows(field, on_map), nan=0.0)
        return _DenseLayer(transform, bev_row.astype(np.float32), bev_col.astype(np.float32),
                           on_map, np.zeros((N_CHANNELS + 1, d + 2 * m, d + 2 * m), np.float32),
                           field, averaged, unrotate_map(averaged, transform))

    def _update_layers(self, bev: BEVMap, changed: Box, near: np.ndarray | None,
                       stats: UpdateStats) -> list[tuple[int, Box]]:
        # ``near`` is not used: the trunk runs over a rectangle either way, and finding the
        # pixels near the mask cost more than it saved (bench_incremental.py)
        m, out = self.model.margin, []
        for k, layer in enumerate(self._layers):
            box = _bbox(_touching(layer.bev_row, layer.bev_col, changed))
            if box is None:
                continue
            channels, observed = rotated_pixels(bev, layer.transform, *box)
            inner = (slice(box[0].start + m, box[0].stop + m),
                     slice(box[1].start + m, box[1].stop + m))
            layer.padded[(slice(0, N_CHANNELS), *inner)] = channels
            layer.padded[(N_CHANNELS, *inner)] = observed
            # windows whose context [a − m, a + 21 + m] × [b − m, b + 6 + m] holds the box
            win = _clip((slice(box[0].start - PATCH_ROWS + 1 - m, box[0].stop + m),
                         slice(box[1].start - PATCH_COLS + 1 - m, box[1].stop + m)),
                        layer.valid.shape)
            if win is None or not layer.valid[win].any():
                continue
            context = layer.padded[:, win[0].start : win[0].stop + PATCH_ROWS - 1 + 2 * m,
                                   win[1].start : win[1].stop + PATCH_COLS - 1 + 2 * m]
            field = self.model.padded_window_field(context, layer.valid[win])[self._heads]
            layer.field[(slice(None), *win)] = np.where(layer.valid[win], field,
                                                         layer.field[(slice(None), *win)])
            stats.windows += int(layer.valid[win].sum())
            cells = _reaverage(self.grid, layer, win)
            if cells is not None:
                out.append((k, cells))
        return out
