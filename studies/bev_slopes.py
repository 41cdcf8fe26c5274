"""How faithful the BEV's H̄, σ_H and ‖∇H̄‖ are on slopes, on rendered surveys of synthetic
terrain, per estimator — and τ_s recomputed with each.

Run: ``.venv/bin/python studies/bev_slopes.py [--tau] [--profile P] [--publish]``
(``--publish`` writes the record whose tables docs/bev.md quotes).

Each world (ramps of 10–28° in four orientations, a 9 m wide 24° ramp between cliffs up
to a plateau, a smooth ridge, a sharp 14° ridge, a bump) is surveyed as every kit world is
(:func:`dgt_lib.world.rendering.survey_frames`, frame seams included) into one
:class:`~dgt_lib.perception.bev.BEVAccumulator`; its map is then read out with

- ``points``: H̄ and σ_H the mean and std of the points in a cell (the paper read
  literally; the kit's BEV before per-cell planes),
- ``plane``: per-cell planes (the default),
- ``plane, fitted slope``: the planes' slopes ‖(a, b)‖ instead of central differences,

and compared with the truth at the cell centres over the observed sloped cells at least 2
cells from the map's border and from kinks of the terrain (cliffs, the ends of a ramp):
|H̄ − h|, |‖∇H̄‖ − ‖∇h‖| (‖∇h‖ the central differences of the true heights, as ‖∇H̄‖ is
of H̄), |σ_H − ‖∇h‖·Δ/√12| (the std of a plane's heights over a Δ-cell), each as
p50 / p99 / max, and the range of ‖∇H̄‖ over the steepest cells.

``--tau`` also recomputes τ_s (``dgt_lib.mapping.occupancy.select_tau_s`` over the
hill's and ridge's known-traversable routes, as ``stages.costmaps.ensure_tau_s`` does)
with each estimator, from fresh surveys of ``--profile``'s worlds (no cache is read or
written).
"""

from __future__ import annotations

import re
import time

import numpy as np
from runner import Study
from scipy import ndimage

from dgt_lib.perception.bev import BEVAccumulator, bev_grid
from dgt_lib.records.study import table
from dgt_lib.world.rendering import survey_frames
from dgt_lib.world.worlds import World, from_heightmap

RES = 0.4


def ramp(angle_deg: float, azimuth_deg: float, n: int = 150, length_m: float = 24.0
         ) -> np.ndarray:
    """Heights of a ramp of ``angle_deg`` rising towards ``azimuth_deg`` over ``length_m``
    across the map's centre, level before and after."""
    x = (np.arange(n) + 0.5) * RES
    gx, gy = np.meshgrid(x, x)
    c, az = n * RES / 2, np.radians(azimuth_deg)
    s = (gx - c) * np.cos(az) + (gy - c) * np.sin(az)
    return np.tan(np.radians(angle_deg)) * (np.clip(s, -length_m / 2, length_m / 2)
                                            + length_m / 2)


def narrow_ramp(angle_deg: float = 24.0, width_m: float = 9.0, n: int = 150) -> np.ndarray:
    """A ``width_m`` wide ramp up to a plateau, between cliffs: level ground for x < 20 m,
    the plateau for x > 40 m, the ramp between (elsewhere the low ground meets the
    plateau's cliff at x = 40 m)."""
    x = (np.arange(n) + 0.5) * RES
    gx, gy = np.meshgrid(x, x)
    t = np.tan(np.radians(angle_deg))
    h = np.where(gx >= 40.0, 20.0 * t, 0.0)
    on = (np.abs(gy - n * RES / 2) <= width_m / 2) & (gx > 20.0) & (gx < 40.0)
    return np.where(on, t * (gx - 20.0), h)


def profile_world(name: str, profile, n: int = 150) -> np.ndarray:
    """Heights of a ridge or bump: ``profile(u)`` of the distance u [m] across it."""
    x = (np.arange(n) + 0.5) * RES
    gx, gy = np.meshgrid(x, x)
    return profile(gx - n * RES / 2, gy - n * RES / 2)


def worlds() -> list[tuple[World, bool]]:
    """The test worlds, each with whether it is piecewise planar (its kinks are then
    left out of the statistics; the ridge and bump are smooth)."""
    out = []
    for angle in (10, 20, 24, 28):
        for az in (0, 30, 45, 73):
            out.append((from_heightmap(ramp(angle, az), RES, name=f"ramp {angle}° az {az}°"),
                        True))
    out.append((from_heightmap(narrow_ramp(), RES, name="9 m ramp 24°, cliffs"), True))
    u = lambda x, y: x * np.cos(0.5) + y * np.sin(0.5)  # noqa: E731
    out.append((from_heightmap(profile_world("smooth ridge", lambda x, y: 1.5 * np.exp(
        -0.5 * (u(x, y) / 1.5) ** 2)), RES, name="smooth ridge 1.5 m"), False))
    out.append((from_heightmap(profile_world("sharp ridge", lambda x, y: np.maximum(
        0.0, 0.7 - np.abs(u(x, y)) * np.tan(np.radians(14)))), RES, name="sharp ridge 14°"),
        True))
    out.append((from_heightmap(profile_world("bump", lambda x, y: 2.0 * np.exp(
        -0.5 * (x**2 + (y + 2) ** 2) / 3.0**2)), RES, name="bump 2 m"), False))
    return out


def smooth_cells(world: World, piecewise_planar: bool, border: int = 2) -> np.ndarray:
    """(H, W) bool: sloped cells (true ‖∇h‖ > 0.01) ≥ ``border`` cells from the map's
    edge and, on piecewise planar terrain, from a kink (a cell whose true heights have a
    second difference along a row or column)."""
    h = world.heights.astype(np.float64)
    ok = np.ones(h.shape, bool)
    if piecewise_planar:
        d2 = np.zeros_like(h)
        d2[1:-1, :] = np.abs(h[2:, :] - 2 * h[1:-1, :] + h[:-2, :])
        d2[:, 1:-1] = np.maximum(d2[:, 1:-1], np.abs(h[:, 2:] - 2 * h[:, 1:-1] + h[:, :-2]))
        ok = ~ndimage.binary_dilation(d2 > 1e-3, iterations=border)
    edge = np.zeros_like(ok)
    edge[border:-border, border:-border] = True
    gx, gy = world.gradient()
    return ok & edge & (np.hypot(gx, gy) > 0.01)


def errors(world: World, acc: BEVAccumulator, piecewise_planar: bool) -> dict[str, tuple]:
    """Per estimator: |H̄ − h|, |‖∇H̄‖ − ‖∇h‖|, |σ_H − ‖∇h‖Δ/√12| as (p50, p99, max) and
    the ‖∇H̄‖ range on the steepest cells, over the observed :func:`smooth_cells`."""
    gx, gy = world.gradient()
    true_grad = np.hypot(gx, gy)
    true_std = true_grad * RES / np.sqrt(12.0)
    out = {}
    for label in ("points", "plane", "plane, fitted slope"):
        bev = acc.result("points" if label == "points" else "plane")
        grad = bev.gradient
        if label == "plane, fitted slope":
            planes = acc.planes()
            grad = np.hypot(planes.slope_x, planes.slope_y)
        sel = bev.observed & smooth_cells(world, piecewise_planar)
        steep = sel & (true_grad >= 0.9 * true_grad[sel].max())
        stats = [np.percentile(np.abs(v - t)[sel], [50, 99, 100]) for v, t in (
            (bev.mean_height, world.heights), (grad, true_grad), (bev.height_std, true_std))]
        out[label] = (*stats, (grad[steep].min(), grad[steep].max(), true_grad[steep].mean()))
    return out


def survey(world: World) -> BEVAccumulator:
    acc = BEVAccumulator(bev_grid(world.grid.extent))
    for frame in survey_frames(world):
        acc.add_frame(frame)
    return acc


def _span(values, digits: int, scale: float = 1.0) -> str:
    """``a`` or ``a–b``: the range of ``values`` over a group of worlds."""
    lo, hi = (f"{scale * v:.{digits}f}" for v in (min(values), max(values)))
    return lo if lo == hi else f"{lo}–{hi}"


def fidelity() -> dict:
    """The error table: one row per terrain (a ramp's four orientations pooled as ranges),
    each estimator's p99 / max of |H̄ − h| [cm] and |‖∇H̄‖ − ‖∇h‖|, and ‖∇H̄‖'s range over
    the steepest cells."""
    groups: dict[str, list[dict]] = {}
    for world, planar in worlds():
        result = errors(world, survey(world), planar)
        name = re.sub(r" az \d+°", ", 4 azimuths", world.name)
        groups.setdefault(name, []).append(result)
        for label, (eh, eg, es, (lo, hi, truth)) in result.items():
            print(f"{world.name:22s} {label:20s} |H̄−h| {eh[1] * 100:.2f}/{eh[2] * 100:.2f} cm"
                  f"  |‖∇H̄‖−‖∇h‖| {eg[1]:.3f}/{eg[2]:.3f}  |σ_H−σ| {es[1] * 100:.2f}/"
                  f"{es[2] * 100:.2f} cm  steepest {lo:.3f}–{hi:.3f} ({truth:.3f})", flush=True)
    rows = []
    for name, results in groups.items():
        row = [name]
        for i, digits, scale in ((0, 2, 100.0), (1, 3, 1.0)):
            for label in ("points", "plane"):
                row.append(" / ".join(_span([r[label][i][q] for r in results], digits, scale)
                                      for q in (1, 2)))
        steep = [_span([r[label][3][j] for r in results for j in (0, 1)], 3)
                 for label in ("points", "plane")]
        truth = _span([r["plane"][3][2] for r in results], 3)
        rows.append([*row, f"{steep[0]} → {steep[1]} ({truth})"])
    return table("The BEV against the true surface: p99 / max over the observed sloped cells",
                 ["terrain", "H̄ error [cm], mean of points", "plane",
                  "‖∇H̄‖ error, mean of points", "plane",
                  "‖∇H̄‖ over the steepest cells (true), mean of points → plane"], rows)


def tau_s(profile: str) -> dict:
    """τ_s with each estimator from fresh surveys of ``profile``'s hill and ridge, and the
    steepest ‖∇H̄‖ each reads on their traversable routes."""
    from dgt_lib.core.config import as_profile
    from dgt_lib.mapping.occupancy import select_tau_s, traversed_gradients
    from dgt_lib.world.terrain import get_world

    prof = as_profile(profile)
    samples: dict[str, list[np.ndarray]] = {"points": [], "plane": []}
    for name in ("hill", "ridge"):
        world = get_world(name, prof)
        acc = BEVAccumulator(bev_grid(world.grid.extent))
        for frame in survey_frames(world, prof.collect):
            acc.add_frame(frame)
        gx, gy = world.gradient()
        for est in samples:
            g = traversed_gradients(world, acc.result(est))
            samples[est].append(g)
            print(f"{profile} {name:6s} {est:7s} steepest traversed ‖∇H̄‖ {g.max():.3f} "
                  f"over {g.size} route cells")
    rows = []
    for est, parts in samples.items():
        g = np.concatenate(parts)
        rows.append([{"points": "mean of points", "plane": "plane"}[est], f"{g.max():.3f}",
                     f"{prof.costmap.tau_s_margin:g}",
                     f"{select_tau_s(g, prof.costmap.tau_s_margin):.3f}"])
    return table(f"τ_s from the `{profile}` hill's and ridge's traversable routes",
                 ["estimator", "steepest traversed ‖∇H̄‖", "margin", "τ_s"], rows)


def main() -> None:
    study = Study("bev_slopes", __doc__, per_seed=False)
    study.parser.add_argument("--tau", action="store_true",
                              help="also recompute τ_s for --profile with each estimator")
    args = study.parse()
    t0 = time.perf_counter()
    tables = {"fidelity": fidelity()}
    if args.tau:
        tables["tau"] = tau_s(args.profile)
    print(f"({time.perf_counter() - t0:.0f} s)")
    study.finish(tables, seeds=[])


if __name__ == "__main__":
    main()
