"""Ground-truth directional locomotion L*(x, y, θ, v): what the network is trained to
predict, measured by driving (paper: Locomotion, Self-Supervised Label Generation; ours:
the paper scores its costmaps only in closed loop).

The vehicle drives a straight line through a cell at heading θ exactly as the data were
collected (:func:`drive_through`: u = 5 m/s, a 15 m run-up) and the paper's formula is
applied in the labels' 1 s window centred on the crossing:

    L* = exp( −1/(2σ²) · ((u·Δt − ‖Δx‖) / (u·Δt))² ),   Δt = 1 s centred on t_c.

A drive ends ``passed``, ``stuck`` (the cell under the vehicle, never crossed: L* =
e^{−4.5}), ``blocked_terrain`` / ``blocked_tree``, ``glitch`` or ``failed``
(:data:`STATUSES`); the cells (:func:`sample_cells`) are stratified by slope, roughness and
route. The rules and why: docs/stages.md → Ground truth. Deterministic and independent of
the run seed; caching and parallel drives are :mod:`dgt_lib.stages.ground_truth`'s job.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from dgt_lib.core.config import CollectConfig, GroundTruthConfig, Profile, as_profile
from dgt_lib.core.executors import limit_threads
from dgt_lib.core.geometry import heading_bins
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.navigation.control.pure_pursuit import PurePursuit
from dgt_lib.perception.episodes import run_episode
from dgt_lib.perception.locomotion import WINDOW_S, locomotion, locomotion_signal
from dgt_lib.world.terrain import get_world
from dgt_lib.world.worlds import PATCH_SIZE_M, World, polyline_distance

STATUSES: tuple[str, ...] = ("passed", "stuck", "blocked_terrain", "blocked_tree", "glitch",
                             "failed")
"""How a ground-truth drive ended (see the module docstring); ``status`` arrays hold the
index into this tuple."""
MEASURED: tuple[str, ...] = ("passed", "stuck")
"""The statuses whose L* is a measurement."""

PATCH_REACH_M = 0.5 * PATCH_SIZE_M[0]
"""How far the patch centred on a cell reaches forward and back along the heading [m]
(``GroundTruthConfig.past_m``: the drive goes on this far past the cell)."""
ROUGHNESS_BLUR_M = 1.0  # σ of the blur that roughness is measured about [m]
ROUGHNESS_WINDOW_M = 2.8  # window of the RMS (the patch's width) [m]
ROUTE_HALF_WIDTH_M = 4.0  # cells this close to a world's route are "on the route" [m]
MOVE_OFF_M = 1.0  # started at rest on a cell, a vehicle that gets this far on is not held [m]
CORRIDOR_CLEARANCE_M = 0.5  # trunks this close to the vehicle's side block a run-up [m]
L_STANDING = float(locomotion(0.0, WINDOW_S))
"""L of a vehicle that does not move, e^{−1/(2σ²)} ≈ 0.011 for σ = 1/3."""


# ----------------------------------------------------------------------------- cells


def cell_features(world: World) -> tuple[np.ndarray, np.ndarray]:
    """Per-cell slope [deg] and roughness [m] of ``world``, each (H, W): the steepest
    slope of the heights, and the RMS over a patch-wide window of the heights about
    their blur of σ = 1 m (a ridge crest, a bump, rock: relief a plane does not fit)."""
    h = world.heights.astype(np.float64)
    res = world.resolution
    residual = h - ndimage.gaussian_filter(h, ROUGHNESS_BLUR_M / res)
    size = max(1, int(round(ROUGHNESS_WINDOW_M / res)) | 1)  # odd
    rough = np.sqrt(np.clip(ndimage.uniform_filter(residual**2, size=size), 0.0, None))
    return world.slope_deg(), rough


def route_cells(world: World, half_width_m: float = ROUTE_HALF_WIDTH_M) -> np.ndarray:
    """(H, W) bool: cells within ``half_width_m`` of one of the world's routes (the hill's
    Routes A and B, the ridge's two crossings, the dirt paths of training and eval)."""
    near = np.zeros(world.grid.shape, bool)
    if world.routes:
        P = np.stack(world.grid.cell_centers(), -1)
        for route in world.routes.values():
            near |= polyline_distance(P, np.asarray(route, np.float64))[0] <= half_width_m
    return near


def cell_strata(world: World, config: GroundTruthConfig) -> np.ndarray:
    """The stratum of every cell, (H, W) int: slope bin (``slope_edges_deg``) × 4 + on a
    route (2) + rough (1; RMS relief above ``roughness_edge_m``, :func:`cell_features`)."""
    slope_deg, roughness_m = cell_features(world)
    slope_bin = np.digitize(slope_deg, np.asarray(config.slope_edges_deg, np.float64))
    return (4 * slope_bin + 2 * route_cells(world)
            + (roughness_m > config.roughness_edge_m)).astype(np.int64)


def candidate_cells(world: World, config: GroundTruthConfig) -> np.ndarray:
    """(H, W) bool: cells that may be sampled — at least ``edge_margin_m`` inside the map,
    ``tree_clearance_m`` from every trunk, at most ``max_slope_deg`` steep."""
    slope, _ = cell_features(world)
    X, Y = world.grid.cell_centers()
    x0, x1, y0, y1 = world.grid.extent
    m = config.edge_margin_m
    ok = (X >= x0 + m) & (X <= x1 - m) & (Y >= y0 + m) & (Y <= y1 - m)
    ok &= slope <= config.max_slope_deg
    if len(world.trees) and ok.any():
        ok[ok] = world.tree_distance(X[ok], Y[ok]) >= config.tree_clearance_m
    return ok


def sample_cells(world: World, config: GroundTruthConfig, n: int | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``n`` (default ``config.cells``) cells of ``world`` stratified by slope and
    roughness: the candidates (:func:`candidate_cells`) of each stratum
    (:func:`cell_strata`) are shuffled (``config.seed``) and drawn in turn, one per
    non-empty stratum, until ``n`` (or every candidate) are drawn.

    Returns (xy (N, 2) cell centres [m], stratum (N,) int), in drawing order."""
    n = config.cells if n is None else n
    ok = candidate_cells(world, config)
    strata = cell_strata(world, config)
    rng = np.random.default_rng(config.seed)
    pools = []
    for s in np.unique(strata[ok]):
        idx = np.flatnonzero(ok.ravel() & (strata.ravel() == s))
        pools.append(list(rng.permutation(idx)))
    chosen: list[int] = []
    while len(chosen) < n and any(pools):
        for pool in pools:
            if pool and len(chosen) < n:
                chosen.append(int(pool.pop(0)))
    flat = np.asarray(chosen, np.int64)
    rows, cols = np.unravel_index(flat, world.grid.shape)
    x, y = world.grid.cell_to_xy(rows, cols)
    return np.stack([x, y], 1).astype(np.float64), strata.ravel()[flat].astype(np.int64)


# ----------------------------------------------------------------------------- one drive


def _corridor_blocked(world: World, a: np.ndarray, b: np.ndarray, half_width_m: float) -> bool:
    """Whether a trunk stands in the rectangular corridor from a to b [m]: its centre
    between the two ends along a → b, its surface within ``half_width_m`` of the line."""
    if len(world.trees) == 0:
        return False
    t = world.trees.astype(np.float64)
    ab = b - a
    length = max(float(np.linalg.norm(ab)), 1e-12)
    u = ab / length
    rel = t[:, :2] - a
    along, across = rel @ u, np.abs(rel @ np.array([-u[1], u[0]]))
    return bool(np.any((along >= 0) & (along <= length) & (across - t[:, 2] < half_width_m)))


def straight_run(world: World, vehicle: str | VehicleSpec, cell, theta: float, start_m: float,
                 config: GroundTruthConfig | None = None, collect: CollectConfig | None = None,
                 until_m: float | None = None):
    """One straight run at heading ``theta`` [rad] from rest ``start_m`` [m] before the
    cell at ``cell`` (x, y) [m] to ``until_m`` (default ``past_m``) beyond it, as the
    data were collected
    (:func:`~dgt_lib.perception.episodes.run_episode`: its PID speed control at
    ``collect.speed_mps``; steering by pure pursuit along the line); it ends there, at a
    stall (``immobilized_limit_s``), a simulator end, or after twice the nominal time plus
    the stall limit. Returns the :class:`~dgt_lib.perception.episodes.Episode` and the
    along-track coordinate [m] of its samples (0 at the cell, positive beyond it)."""
    config = config or GroundTruthConfig()
    collect = collect or CollectConfig()
    until_m = config.past_m if until_m is None else until_m
    cell = np.asarray(cell, np.float64)
    direction = np.array([math.cos(theta), math.sin(theta)])
    start = cell - start_m * direction
    line = np.stack([start, cell + (until_m + 20.0) * direction])
    nominal_s = (start_m + until_m) / collect.speed_mps
    cfg = replace(collect, episode_duration_s=2.0 * nominal_s + collect.immobilized_limit_s)
    ep = run_episode(world, vehicle, 0, cfg, start_pose=np.array([*start, theta]),
                     steer=PurePursuit(line, get_vehicle(vehicle)), render=False,
                     stop=lambda st: float((st.position[:2] - cell) @ direction) >= until_m)
    along = (np.asarray(ep.pose[:, :2], np.float64) - cell) @ direction
    return ep, along


def drive_through(world: World, vehicle: str | VehicleSpec, xy, theta: float,
                  config: GroundTruthConfig | None = None,
                  collect: CollectConfig | None = None) -> dict[str, float | int]:
    """Drive ``vehicle`` straight through the cell at ``xy`` [m] at heading ``theta``
    [rad] and measure L* there (see the module docstring).

    Returns ``status`` (index into :data:`STATUSES`), ``locomotion`` (L*, NaN unless
    measured), ``speed_mps`` (speed when the centre crossed the cell, NaN if it did not),
    ``cross_track_m`` (the centre's distance from the line through the cell then),
    ``stop_along_m`` (how far a run that did not cross the cell got — for ``blocked_*``
    the run-up —, the centre's farthest point relative to the cell along the heading;
    NaN if it crossed) and ``sim_s`` (simulated seconds, both drives)."""
    gt = config or GroundTruthConfig()
    col = collect or CollectConfig()
    spec = get_vehicle(vehicle)
    cell = np.asarray(xy, np.float64)
    d = np.array([math.cos(theta), math.sin(theta)])
    half_width = 0.5 * spec.width_m + CORRIDOR_CLEARANCE_M
    half_length = 0.5 * spec.length_m  # from here on the cell is under the vehicle
    out = {"status": 0, "locomotion": math.nan, "speed_mps": math.nan,
           "cross_track_m": math.nan, "stop_along_m": math.nan, "sim_s": 0.0}
    ended = {"failed": STATUSES.index("failed"), "stuck": STATUSES.index("stuck")}
    # A trunk the front meets before the cell is under the vehicle blocks the run-up.
    if _corridor_blocked(world, cell - (gt.run_up_m + half_length) * d, cell, half_width):
        blocked = "blocked_tree"
    else:
        ep, along = straight_run(world, spec, cell, theta, gt.run_up_m, gt, col)
        out["sim_s"] += float(ep.time_s[-1])
        if along.max() >= 0:
            return {**out, **_crossing(ep, along, cell, d, col)}
        out["stop_along_m"] = float(along.max())
        if ep.end_reason in ("off_map", "diverged"):
            return {**out, "status": ended["failed"]}
        if along.max() >= -half_length:  # stopped for good with the cell under it
            return {**out, "status": ended["stuck"], "locomotion": L_STANDING}
        blocked = "blocked_terrain"
    # Blocked: does the cell's own terrain hold the vehicle? Start at rest on the cell.
    if _corridor_blocked(world, cell - half_length * d, cell + half_length * d, half_width):
        return {**out, "status": STATUSES.index(blocked)}  # no room to start on it
    ep, along = straight_run(world, spec, cell, theta, 0.0, gt, col, until_m=MOVE_OFF_M)
    out["sim_s"] += float(ep.time_s[-1])
    if ep.end_reason in ("off_map", "diverged"):
        return {**out, "status": ended["failed"]}
    if along.max() >= MOVE_OFF_M:  # it drives off: L* at speed is unknown
        return {**out, "status": STATUSES.index(blocked)}
    return {**out, "status": ended["stuck"], "locomotion": L_STANDING}


def _crossing(ep, along: np.ndarray, cell: np.ndarray, d: np.ndarray,
              collect: CollectConfig) -> dict[str, float | int]:
    """A run that crossed the cell: L in the window centred on the crossing, the speed
    and cross-track offset then (``glitch`` if the window touches one)."""
    t = np.asarray(ep.time_s, np.float64)
    xy_run = np.asarray(ep.pose[:, :2], np.float64)
    i = int(np.argmax(along >= 0))
    t_c = t[0] if i == 0 else float(np.interp(0.0, along[i - 1:i + 1], t[i - 1:i + 1]))
    span = min(WINDOW_S, t[-1] - t[0])
    lo = float(np.clip(t_c - 0.5 * span, t[0], t[-1] - span))
    in_window = (t >= lo - 1e-9) & (t <= lo + span + 1e-9)
    if not np.all(ep.valid[in_window]):
        return {"status": STATUSES.index("glitch")}
    p_c = np.array([np.interp(t_c, t, xy_run[:, 0]), np.interp(t_c, t, xy_run[:, 1])])
    return {"status": STATUSES.index("passed"),
            "locomotion": float(locomotion_signal(t, xy_run, u=collect.speed_mps,
                                                  at_s=np.array([t_c]))[0]),
            "speed_mps": float(np.interp(t_c, t, ep.speed_mps)),
            "cross_track_m": float(abs((p_c - cell) @ np.array([-d[1], d[0]])))}


def drive_job(profile: Profile, world_name: str, vehicle: str | VehicleSpec, x: float, y: float,
              theta: float) -> dict[str, float | int]:
    """Worker entry point: :func:`drive_through` on the profile's world ``world_name``."""
    limit_threads()  # a Dask worker has no initializer of ours
    prof = as_profile(profile)
    return drive_through(get_world(world_name, prof), vehicle, (x, y), theta,
                         prof.ground_truth, prof.collect)


# ----------------------------------------------------------------------------- the result


@dataclass
class GroundTruth:
    """L* of one vehicle on sampled cells of one world at K headings.

    cells: (N, 2) cell centres [m]; stratum: (N,) :func:`cell_strata` of each;
    headings: (K,) θ_k = 2πk/K [rad]; locomotion: (N, K) L* (NaN where not measured);
    status: (N, K) int index into :data:`STATUSES`; speed_mps, cross_track_m: (N, K)
    at the crossing (NaN where the vehicle did not cross).
    """

    world: str
    vehicle: str
    cells: np.ndarray
    stratum: np.ndarray
    headings: np.ndarray
    locomotion: np.ndarray
    status: np.ndarray
    speed_mps: np.ndarray
    cross_track_m: np.ndarray

    @property
    def cost(self) -> np.ndarray:
        """(N, K) C* = 1 − L* (NaN where not measured)."""
        return 1.0 - self.locomotion

    @property
    def measured(self) -> np.ndarray:
        """(N, K) bool: the samples whose L* was measured (:data:`MEASURED`)."""
        return np.isin(self.status, [STATUSES.index(s) for s in MEASURED])

    def status_counts(self) -> dict[str, int]:
        """How many samples ended with each status, in :data:`STATUSES` order."""
        return {s: int(np.sum(self.status == i)) for i, s in enumerate(STATUSES)}

    def summary(self) -> str:
        """One line: samples, measured, mean L*, and the unmeasured by status."""
        counts = self.status_counts()
        n, m = self.status.size, int(self.measured.sum())
        mean = f"{np.nanmean(self.locomotion):.2f}" if m else "—"
        rest = ", ".join(f"{s} {c}" for s, c in counts.items() if c and s not in MEASURED)
        return (f"{self.world}/{self.vehicle}: {len(self.cells)} cells × {len(self.headings)} "
                f"headings, {m}/{n} measured (stuck {counts['stuck']}), mean L* {mean}"
                + (f"; not measured: {rest}" if rest else ""))

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {"world": np.array(self.world), "vehicle": np.array(self.vehicle),
                "cells": self.cells, "stratum": self.stratum, "headings": self.headings,
                "locomotion": self.locomotion, "status": self.status,
                "speed_mps": self.speed_mps, "cross_track_m": self.cross_track_m}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> GroundTruth:
        return cls(world=str(arrays["world"]), vehicle=str(arrays["vehicle"]),
                   **{k: arrays[k] for k in ("cells", "stratum", "headings", "locomotion",
                                             "status", "speed_mps", "cross_track_m")})

    @classmethod
    def from_drives(cls, world: str, vehicle: str, cells: np.ndarray, stratum: np.ndarray,
                    n_headings: int, drives: dict[tuple[int, int], dict]) -> GroundTruth:
        """Assemble from ``{(cell index, heading index): drive_through result}``, which
        must hold every cell at every heading."""
        shape = (len(cells), n_headings)
        missing = [(i, k) for i in range(shape[0]) for k in range(shape[1])
                   if (i, k) not in drives]
        if missing:
            raise ValueError(f"{world}/{vehicle}: {len(missing)} of {shape[0] * shape[1]} "
                             f"drives missing, e.g. cell {missing[0][0]} heading {missing[0][1]}")
        arrays = {k: np.full(shape, np.nan) for k in ("locomotion", "speed_mps",
                                                      "cross_track_m")}
        status = np.zeros(shape, np.int8)
        for (i, k), rec in drives.items():
            status[i, k] = rec["status"]
            for name in arrays:
                arrays[name][i, k] = rec[name]
        return cls(world, vehicle, np.asarray(cells, np.float64),
                   np.asarray(stratum, np.int64), heading_bins(n_headings), status=status,
                   **arrays)

