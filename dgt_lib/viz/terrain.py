"""Figures and tables of notebook 01 (terrain, vehicles and the bird's-eye view).

Paper: Methodology → Global Map, and the vehicles of Experiments.

- worlds, vehicles, RGB-D frames and premise runs (first half): hill-shaded heights
  and textures, slope histograms, the vehicle table, camera frames and chase views,
  speed against distance;
- the BEV map (second half): back-projected points, the survey lattice and its
  footprints (:func:`survey_footprints`), the six channels, the error against the true
  terrain (:func:`height_errors`) and a quality table.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LightSource

from dgt_lib.core.config import VEHICLES
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.viz.common import _masked, _overlay
from dgt_lib.world.worlds import World


def plot_world(world: World, axes: Sequence | None = None, *, labels: bool = True):
    """Two panels: hill-shaded heights [m] and the colour texture, both with routes,
    trees and landmarks. Returns the figure."""
    if axes is None:
        fig, axes = plt.subplots(1, 2, figsize=(11, 5), constrained_layout=True)
    fig = axes[0].figure
    shade = LightSource(azdeg=315, altdeg=45).hillshade(
        world.heights.astype(np.float64), vert_exag=2.0, dx=world.resolution,
        dy=world.resolution)
    im = axes[0].imshow(world.heights, origin="lower", extent=world.extent, cmap="terrain")
    axes[0].imshow(shade, origin="lower", extent=world.extent, cmap="gray", alpha=0.35)
    fig.colorbar(im, ax=axes[0], shrink=0.8, label="height [m]")
    axes[1].imshow(world.colors, origin="lower", extent=world.extent)
    for ax, title in zip(axes, ("heights", "colour texture"), strict=True):
        _overlay(ax, world, labels=labels)
        ax.set_title(f"{world.name}: {title}")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    if world.routes:
        axes[0].legend(loc="lower right", fontsize=7)
    return fig


def plot_worlds(worlds: Sequence[World]):
    """One row per world: heights and colours (see :func:`plot_world`)."""
    fig, axes = plt.subplots(len(worlds), 2, figsize=(11, 5 * len(worlds)),
                             constrained_layout=True, squeeze=False)
    for w, row in zip(worlds, axes, strict=True):
        plot_world(w, row, labels=w.name in ("hill", "ridge"))
    return fig


def plot_slope_histogram(worlds: Sequence[World]):
    """Histogram of cell slopes [deg] per world, with each vehicle's torque-limited
    climbing grade marked."""
    _, ax = plt.subplots(figsize=(7, 3.5), constrained_layout=True)
    for w in worlds:
        ax.hist(w.slope_deg().ravel(), bins=np.arange(0, 61, 1.0), histtype="step",
                density=True, label=w.name)
    for name in VEHICLES:
        ax.axvline(get_vehicle(name).max_climb_deg, ls=":", color="gray")
        ax.text(get_vehicle(name).max_climb_deg, ax.get_ylim()[1] * 0.9, name, rotation=90,
                fontsize=7, va="top")
    ax.set_xlabel("slope [deg]")
    ax.set_ylabel("fraction of cells / deg")
    ax.legend()
    return ax.figure


def vehicle_table() -> str:
    """The four vehicle specs as a Markdown table (units in the header)."""
    cols = [("wheelbase [m]", "wheelbase_m"), ("track [m]", "track_m"),
            ("length [m]", "length_m"), ("width [m]", "width_m"),
            ("clearance [m]", "ground_clearance_m"), ("wheel r [m]", "wheel_radius_m"),
            ("mass [kg]", "mass_kg"), ("drive", "drive"),
            ("torque/wheel [N·m]", "drive_torque_nm"), ("max steer [deg]", "max_steer_rad"),
            ("min turn R [m]", "min_turn_radius_m"), ("max climb [deg]", "max_climb_deg")]
    lines = ["| vehicle | " + " | ".join(c[0] for c in cols) + " |",
             "|---" * (len(cols) + 1) + "|"]
    for name in VEHICLES:
        v = get_vehicle(name)
        cells = []
        for _, attr in cols:
            val = getattr(v, attr)
            if attr == "max_steer_rad":
                val = math.degrees(val)
            cells.append(f"{val:.4g}" if isinstance(val, float) else str(val))
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot_images(images: Mapping[str, np.ndarray], ncols: int = 4):
    """A grid of RGB images with titles."""
    n = len(images)
    nrows = math.ceil(n / ncols)
    fig, axes = plt.subplots(nrows, min(n, ncols), figsize=(3.6 * min(n, ncols), 2.9 * nrows),
                             constrained_layout=True, squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, (title, img) in zip(axes.ravel(), images.items(), strict=False):
        ax.imshow(img)
        ax.set_title(title)
    return fig


def plot_rgbd(frame, title: str = ""):
    """RGB and depth [m] of an :class:`~dgt_lib.core.camera.RGBDFrame` side by side
    (NaN depth, i.e. sky or beyond range, is white)."""
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4), constrained_layout=True)
    axes[0].imshow(frame.rgb)
    axes[0].set_title(f"{title} RGB".strip())
    im = axes[1].imshow(frame.depth, cmap="viridis")
    axes[1].set_title("depth (NaN = white)")
    fig.colorbar(im, ax=axes[1], label="depth [m]")
    for ax in axes:
        ax.axis("off")
    return fig


def plot_speed_vs_distance(runs: Mapping[str, object], title: str = ""):
    """Measured speed [m/s] against signed distance driven [m] for several
    :class:`~dgt_lib.navigation.drive.Trajectory` runs, each labelled with how it ended, with
    height along the run on a second axis."""
    _, ax = plt.subplots(figsize=(8, 3.8), constrained_layout=True)
    ax2 = ax.twinx()
    for i, (label, tr) in enumerate(runs.items()):
        color = f"C{i}"
        dist = tr.progress_m
        ax.plot(dist, tr.speed_mps, color=color, label=f"{label} → {tr.end_reason}")
        ax2.plot(dist, tr.position[:, 2], color=color, ls=":", alpha=0.7)
    ax.axhline(5.0, color="gray", lw=0.8, ls="--")
    ax.set_xlabel("distance driven along the heading [m]")
    ax.set_ylabel("speed [m/s] (solid)")
    ax2.set_ylabel("height [m] (dotted)")
    ax.set_title(title)
    ax.legend(fontsize=8, loc="lower right")
    return ax.figure


def chase_view(sim, *, distance_m: float = 9.0, height_m: float = 4.0, side_deg: float = 140.0,
               size: tuple[int, int] = (320, 240)) -> np.ndarray:
    """An RGB picture of the simulated vehicle: (height, width, 3) uint8 from a camera
    ``distance_m`` away and ``height_m`` up, ``side_deg`` round from straight behind
    (default: a front-left three-quarter view)."""
    from dgt_lib.core.camera import CameraIntrinsics
    from dgt_lib.world.simulator import look_at

    st = sim.state
    ang = st.yaw + math.pi + math.radians(side_deg)
    target = st.position + np.array([0.0, 0.0, 0.8])
    eye = target + np.array([distance_m * math.cos(ang), distance_m * math.sin(ang), height_m])
    frame = sim.render_rgbd(look_at(eye, target), show_vehicle=True,
                            intrinsics=CameraIntrinsics(size[0], size[1], math.radians(45.0)))
    return frame.rgb


def survey_footprints(world: World, poses: Sequence[tuple[np.ndarray, np.ndarray]],
                      intrinsics) -> np.ndarray:
    """Ground footprint of each camera pose: (N, 4) boxes (x_min, x_max, y_min, y_max) [m].

    The four image-corner rays of a camera at ``position`` with ``rotation``
    (world_from_camera; the camera looks along −z) are intersected with the
    horizontal plane at the terrain height below the camera; the box bounds
    the four hits. For a nadir camera D above flat ground this is the rectangle
    2D·tan(hfov/2) × 2D·tan(vfov/2). Raises ``ValueError`` for a camera whose
    corner rays do not all point down.
    """
    from dgt_lib.world.rendering import _tan_half_fov

    tan_x, tan_y = _tan_half_fov(intrinsics)
    corners = np.array([[sx * tan_x, sy * tan_y, -1.0] for sx in (-1, 1) for sy in (-1, 1)])
    boxes = np.empty((len(poses), 4))
    for i, (position, rotation) in enumerate(poses):
        p = np.asarray(position, np.float64)
        rays = corners @ np.asarray(rotation, np.float64).T  # (4, 3) world directions
        if np.any(rays[:, 2] >= 0):
            raise ValueError(f"camera {i} does not look down: its footprint is unbounded")
        ground = float(world.height_at(p[0], p[1]))
        hits = p + rays * ((ground - p[2]) / rays[:, 2])[:, None]
        boxes[i] = hits[:, 0].min(), hits[:, 0].max(), hits[:, 1].min(), hits[:, 1].max()
    return boxes


def plot_survey(world: World, poses: Sequence[tuple[np.ndarray, np.ndarray]], intrinsics):
    """The mapping survey over a world's heights: camera positions (dots, numbered
    in order) and their ground footprints (:func:`survey_footprints`)."""
    from matplotlib.patches import Rectangle

    _, ax = plt.subplots(figsize=(6.5, 6), constrained_layout=True)
    im = ax.imshow(world.heights, origin="lower", extent=world.extent, cmap="terrain")
    ax.figure.colorbar(im, ax=ax, shrink=0.8, label="height [m]")
    boxes = survey_footprints(world, poses, intrinsics)
    for i, ((x0, x1, y0, y1), (pos, _)) in enumerate(zip(boxes, poses, strict=True)):
        color = f"C{i % 10}"
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec=color, lw=1.0))
        ax.plot(pos[0], pos[1], "o", ms=4, color=color)
        ax.annotate(str(i), (pos[0], pos[1]), xytext=(3, 3), textcoords="offset points",
                    fontsize=7)
    ax.set_xlim(world.extent[:2])
    ax.set_ylim(world.extent[2:])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{world.name}: {len(poses)} survey frames and their ground footprints")
    return ax.figure


def plot_backprojection(frame, world: World, title: str = ""):
    """The points of one RGB-D frame seen from above: coloured by their pixel (left)
    and by their height error z − h(x, y) against the true terrain [cm] (right),
    with the camera's position and viewing direction."""
    points, colors = frame.points_world()
    err_cm = 100.0 * (points[:, 2] - world.height_at(points[:, 0], points[:, 1]))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6), constrained_layout=True)
    lim = max(float(np.percentile(np.abs(err_cm), 99)), 1.0)
    axes[0].scatter(points[:, 0], points[:, 1], c=colors, s=1, linewidths=0)
    sc = axes[1].scatter(points[:, 0], points[:, 1], c=err_cm, s=1, linewidths=0,
                         cmap="coolwarm", vmin=-lim, vmax=lim)
    fig.colorbar(sc, ax=axes[1], label="z − h(x, y) [cm]")
    view = -np.asarray(frame.rotation)[:, 2]  # the camera looks along its −z axis
    pos = np.asarray(frame.position)
    for ax, sub in zip(axes, ("points in pixel colour", "height error"), strict=True):
        ax.plot(pos[0], pos[1], "k^", ms=8, label="camera")
        ax.annotate("", xy=pos[:2] + 6.0 * view[:2] / max(np.linalg.norm(view[:2]), 1e-9),
                    xytext=pos[:2], arrowprops={"arrowstyle": "->", "color": "black"})
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f"{title} {sub}".strip())
    axes[0].legend(loc="lower right", fontsize=8)
    return fig


def plot_bev(bev, title: str = "", region: tuple[float, float, float, float] | None = None,
             percentiles: tuple[float, float] = (99.0, 90.0)):
    """The six BEV channels: R, G, B as one colour image, then H̄ [m], σ_H [m] and
    ‖∇H̄‖ [m/m] with colour bars. σ_H and ‖∇H̄‖ are scaled from 0 to the given
    percentiles of their observed cells (default 99th: σ_H is large on trees only;
    90th: the gradient of the open ground shows, tree rings saturate). Unobserved
    cells are light grey. region: optional (x_min, x_max, y_min, y_max) [m] to zoom
    into; the colour scales then come from the cells inside it."""
    fig, axes = plt.subplots(1, 4, figsize=(17, 4.4), constrained_layout=True)
    obs = bev.observed
    shown = obs
    if region is not None:
        x, y = bev.grid.cell_centers()
        shown = obs & (x >= region[0]) & (x <= region[1]) & (y >= region[2]) & (y <= region[3])
    rgb = np.where(obs[..., None], np.clip(bev.rgb, 0, 1), 0.85)
    axes[0].imshow(rgb, origin="lower", extent=bev.grid.extent)
    axes[0].set_title("R, G, B")
    layers = (("H̄ [m]", bev.mean_height, "terrain", None),
              ("σ_H [m]", bev.height_std, "magma", percentiles[0]),
              ("‖∇H̄‖ [m/m]", bev.gradient, "viridis", percentiles[1]))
    for ax, (name, layer, cmap, pct) in zip(axes[1:], layers, strict=True):
        values = layer[shown]
        if not values.size:
            vmin = vmax = None
        elif pct is None:
            vmin, vmax = float(values.min()), float(values.max())
        else:
            vmin, vmax = 0.0, float(np.percentile(values, pct))
        cm = plt.get_cmap(cmap).copy()
        cm.set_bad("0.85")
        im = ax.imshow(_masked(layer, obs), origin="lower", extent=bev.grid.extent, cmap=cm,
                       vmin=vmin, vmax=vmax)
        fig.colorbar(im, ax=ax, shrink=0.85, label=name,
                     extend="max" if pct is not None else "neither")
        ax.set_title(name.split(" ")[0])
    for ax in axes:
        if region is not None:
            ax.set_xlim(region[:2])
            ax.set_ylim(region[2:])
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
    axes[0].set_ylabel("y [m]")
    if title:
        fig.suptitle(title)
    return fig


def height_errors(bev, world: World) -> np.ndarray:
    """(H, W) signed error H̄ − h [m] of every observed BEV cell whose centre lies in
    the world's interior, h the true terrain height at the cell centre; NaN elsewhere.
    Its median absolute value is :func:`dgt_lib.perception.bev.bev_quality`'s
    ``height_median_abs_err_m``."""
    x, y = bev.grid.cell_centers()
    x0, x1, y0, y1 = world.interior
    inside = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1) & bev.observed
    err = np.full(bev.grid.shape, np.nan)
    err[inside] = bev.mean_height[inside] - world.height_at(x[inside], y[inside])
    return err


def plot_bev_error(bev, world: World, title: str = ""):
    """Where and how much the map's H̄ differs from the true terrain: the signed error
    H̄ − h on the map (left; trees stand out as positive) and a histogram of |H̄ − h|
    on a log axis with its median and 95th percentile (right)."""
    err = height_errors(bev, world)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6), constrained_layout=True)
    seen = np.isfinite(err)
    lim = max(float(np.percentile(np.abs(err[seen]), 99)), 0.01) if seen.any() else 1.0
    cm = plt.get_cmap("coolwarm").copy()
    cm.set_bad("0.85")
    im = axes[0].imshow(np.ma.masked_invalid(err), origin="lower", extent=bev.grid.extent,
                        cmap=cm, vmin=-lim, vmax=lim)
    fig.colorbar(im, ax=axes[0], shrink=0.85, label="H̄ − h [m]", extend="both")
    axes[0].set_aspect("equal")
    axes[0].set_xlabel("x [m]")
    axes[0].set_ylabel("y [m]")
    axes[0].set_title(f"{title} H̄ − h (grey: unobserved or outside)".strip())
    a = np.abs(err[seen])
    lo = max(float(a.min()), 1e-4) if a.size else 1e-4
    hi = max(float(a.max()), lo * 10)
    axes[1].hist(np.maximum(a, lo), bins=np.geomspace(lo, hi, 60), color="0.4")
    axes[1].set_xscale("log")
    axes[1].set_yscale("log")
    for q, ls in ((50, "-"), (95, "--")):
        v = float(np.percentile(a, q)) if a.size else math.nan
        axes[1].axvline(v, color="tab:red", ls=ls, label=f"{q}th percentile: {v * 100:.1f} cm")
    axes[1].set_xlabel("|H̄ − h| [m]")
    axes[1].set_ylabel("cells")
    axes[1].set_title(f"{a.size} observed cells")
    axes[1].legend()
    return fig


def quality_table(rows: Mapping[str, Mapping[str, float]]) -> str:
    """A Markdown table of :func:`dgt_lib.perception.bev.bev_quality` results, one row per map."""
    lines = ["| map | coverage | median \\|H̄ − h\\| [cm] |", "|---|---|---|"]
    for name, q in rows.items():
        lines.append(f"| {name} | {q['coverage']:.1%} | "
                     f"{q['height_median_abs_err_m'] * 100:.2f} |")
    return "\n".join(lines)
