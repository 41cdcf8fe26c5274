"""Matplotlib figures and small Markdown tables for the notebooks.

- worlds, vehicles, RGB-D frames and premise runs (notebook 01, first half);
- the BEV map: back-projected points, the survey lattice, the six channels, the
  error against the true terrain (notebook 01, second half);
- locomotion labels: L against the speed ratio, L(t) along runs, the dataset's
  counts, label histograms, a patch gallery and L against forward slope (notebook 02);
- Hybrid A*: the three primitives and the costmap layer each reads, the cost
  amplification C'(C), planned paths and expanded nodes, a table of plans (notebook 05);
- :func:`source_markdown` to show an implementation next to its paper equation.

Every plotting function returns the matplotlib ``Figure`` (or draws into a given
``ax``), so notebooks stay one call per picture; the few functions that compute
something (:func:`survey_footprints`, :func:`height_errors`, :func:`gallery_indices`,
:func:`binned_mean`, the ``*_table`` functions) are tested in ``tests/test_viz.py``
(:func:`primitive_lookups` and :func:`plan_table` in ``tests/test_viz_planner.py``)::

    from dgt_lib import viz
    viz.plot_world(get_world("hill"))
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LightSource

from dgt_lib.config import VEHICLES
from dgt_lib.vehicles import get_vehicle
from dgt_lib.worlds import World

ROUTE_COLORS = ("tab:blue", "tab:orange", "tab:purple", "tab:cyan", "tab:pink", "tab:olive")


def _overlay(ax, world: World, trees: bool = True, labels: bool = True) -> None:
    for i, (name, line) in enumerate(world.routes.items()):
        ax.plot(line[:, 0], line[:, 1], "--", lw=1.5, color=ROUTE_COLORS[i % len(ROUTE_COLORS)],
                label=f"route {name}")
    if trees and len(world.trees):
        ax.scatter(world.trees[:, 0], world.trees[:, 1], s=8, c="darkgreen", marker="^",
                   label="trees")
    for name, (x, y) in world.landmarks.items():
        ax.plot(x, y, "o", ms=5, mfc="white", mec="black")
        if labels:
            ax.annotate(name, (x, y), xytext=(3, 3), textcoords="offset points", fontsize=7)
    ax.set_xlim(world.extent[:2])
    ax.set_ylim(world.extent[2:])
    ax.set_aspect("equal")


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


def plot_slope_histogram(worlds: Sequence[World], ax=None):
    """Histogram of cell slopes [deg] per world, with each vehicle's torque-limited
    climbing grade marked."""
    if ax is None:
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
    """RGB and depth [m] of an :class:`~dgt_lib.camera.RGBDFrame` side by side
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


def plot_speed_vs_distance(runs: Mapping[str, object], ax=None, title: str = ""):
    """Measured speed [m/s] against signed distance driven [m] for several
    :class:`~dgt_lib.sim.Trajectory` runs, each labelled with how it ended, with
    height along the run on a second axis."""
    if ax is None:
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
    from dgt_lib.camera import CameraIntrinsics
    from dgt_lib.sim import look_at

    st = sim.state
    ang = st.yaw + math.pi + math.radians(side_deg)
    target = st.position + np.array([0.0, 0.0, 0.8])
    eye = target + np.array([distance_m * math.cos(ang), distance_m * math.sin(ang), height_m])
    frame = sim.render_rgbd(look_at(eye, target), show_vehicle=True,
                            intrinsics=CameraIntrinsics(size[0], size[1], math.radians(45.0)))
    return frame.rgb


# ----------------------------------------------------------------------------- source next to math

VEHICLE_COLORS: dict[str, str] = dict(zip(VEHICLES, ("tab:green", "tab:blue", "tab:purple",
                                                     "tab:red"), strict=True))
"""One colour per vehicle, used by every per-vehicle figure."""


def source_markdown(obj) -> str:
    """A function's or class's source as a fenced Markdown code block, headed by where
    it lives (``dgt_lib/bev.py``, line N), to show an implementation next to the
    paper's equation: ``display(Markdown(viz.source_markdown(bev.height_gradient)))``."""
    import inspect
    from pathlib import Path

    lines, start = inspect.getsourcelines(obj)
    path = Path(inspect.getsourcefile(obj)).resolve()
    parts = path.parts
    shown = "/".join(parts[parts.index("dgt_lib"):]) if "dgt_lib" in parts else path.name
    return (f"`{shown}`, line {start}: `{obj.__qualname__}`\n\n```python\n"
            + "".join(lines).rstrip() + "\n```")


# ----------------------------------------------------------------------------- BEV map


def _tan_half_fov(intrinsics) -> tuple[float, float]:
    """tan of the half field of view across (image width) and along (image height)."""
    tan_y = math.tan(0.5 * intrinsics.fovy_rad)
    return tan_y * intrinsics.width / intrinsics.height, tan_y


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


def plot_survey(world: World, poses: Sequence[tuple[np.ndarray, np.ndarray]], intrinsics,
                ax=None):
    """The mapping survey over a world's heights: camera positions (dots, numbered
    in order) and their ground footprints (:func:`survey_footprints`)."""
    from matplotlib.patches import Rectangle

    if ax is None:
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


def _masked(layer: np.ndarray, observed: np.ndarray) -> np.ma.MaskedArray:
    return np.ma.masked_array(layer, mask=~observed)


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
    Its median absolute value is :func:`dgt_lib.collect.bev_quality`'s
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
    """A Markdown table of :func:`dgt_lib.collect.bev_quality` results, one row per map."""
    lines = ["| map | coverage | median \\|H̄ − h\\| [cm] |", "|---|---|---|"]
    for name, q in rows.items():
        lines.append(f"| {name} | {q['coverage']:.1%} | "
                     f"{q['height_median_abs_err_m'] * 100:.2f} |")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- locomotion labels

PAPER_DATASET: dict[str, tuple[int, int]] = {
    "jeep": (30_000, 400), "vw_van": (10_000, 400), "mercedes_van": (10_000, 300),
    "carla_cola": (2_000, 200),
}
"""(patches, trajectories) per vehicle as the paper reports them (Experiments → Dataset)."""


def plot_locomotion_curve(u: float | None = None, sigma: float | None = None, ax=None):
    """L (solid) and the cost C = 1 − L (dashed) against the speed ratio
    ‖Δx‖ / (u·Δt) from standing still (0) to twice the commanded speed (2),
    computed by :func:`dgt_lib.locomotion.locomotion`."""
    from dgt_lib.locomotion import SIGMA, TARGET_SPEED_MPS, locomotion

    u = TARGET_SPEED_MPS if u is None else u
    sigma = SIGMA if sigma is None else sigma
    if ax is None:
        _, ax = plt.subplots(figsize=(6.5, 3.6), constrained_layout=True)
    ratio = np.linspace(0.0, 2.0, 401)
    dt = 1.0  # [s]; L depends on the ratio only
    L = locomotion(ratio * u * dt, dt, u=u, sigma=sigma)
    ax.plot(ratio, L, color="k", label="locomotion L")
    ax.plot(ratio, 1.0 - L, color="k", ls="--", label="cost C = 1 − L")
    for r in (0.0, 0.5):
        v = float(locomotion(r * u * dt, dt, u=u, sigma=sigma))
        ax.plot(r, v, "o", color="tab:red")
        ax.annotate(f"L({r:g}) = {v:.3f}", (r, v), xytext=(6, 6), textcoords="offset points")
    ax.set_xlabel("speed ratio ‖Δx‖ / (u·Δt)")
    ax.set_ylabel("L, C")
    ax.set_title(f"u = {u:g} m/s, σ = {sigma:.3g}")
    ax.set_ylim(-0.02, 1.05)
    ax.legend(loc="center right")
    return ax.figure


def _patch_outline(pose: np.ndarray) -> np.ndarray:
    """(4, 2) world corners of the 8.8 m × 2.8 m patch at pose (x, y, θ)."""
    from dgt_lib.patches import PATCH_LENGTH_M, PATCH_WIDTH_M, body_to_world

    f, w = 0.5 * PATCH_LENGTH_M, 0.5 * PATCH_WIDTH_M
    corners = np.array([[f, w], [f, -w], [-f, -w], [-f, w]])
    x, y = body_to_world(np.asarray(pose, np.float64)[None], corners)
    return np.stack([x[0], y[0]], axis=1)


def plot_run_labels(runs: Mapping[str, object], bev, config=None):
    """Locomotion along recorded runs (:class:`dgt_lib.collect.Episode`), one colour each.

    Left: speed [m/s] (solid) and chassis height [m] (dotted) against time.
    Middle: L(t) from the sliding window (:func:`dgt_lib.locomotion.locomotion_signal`)
    with the patches the dataset cuts from the run (dots at (t_P, L(t_P)),
    :func:`dgt_lib.dataset.episode_patches`). Right: the paths on the BEV map,
    coloured by L, with every patch's 8.8 m × 2.8 m outline.
    """
    from matplotlib.collections import LineCollection

    from dgt_lib.dataset import episode_patches
    from dgt_lib.locomotion import locomotion_signal

    fig, axes = plt.subplots(1, 3, figsize=(17, 4.6), constrained_layout=True,
                             gridspec_kw={"width_ratios": [1.1, 1.1, 1.0]})
    ax_h = axes[0].twinx()
    xy_all = []
    for i, (label, ep) in enumerate(runs.items()):
        color = f"C{i}"
        t = np.asarray(ep.time_s, np.float64)
        L = locomotion_signal(t, ep.pose[:, :2])
        cut = episode_patches(ep, bev, config)
        axes[0].plot(t, ep.speed_mps, color=color, label=f"{label} → {ep.end_reason}")
        ax_h.plot(t, ep.z, color=color, ls=":", alpha=0.7)
        axes[1].plot(t, L, color=color, label=label)
        axes[1].plot(cut["times"], cut["labels"], "o", ms=4, color=color, mec="black")
        xy = np.asarray(ep.pose[:, :2], np.float64)
        xy_all.append(xy)
        segs = LineCollection(np.stack([xy[:-1], xy[1:]], axis=1), cmap="RdYlGn",
                              norm=plt.Normalize(0, 1), linewidths=2.5)
        segs.set_array(0.5 * (L[1:] + L[:-1]))
        axes[2].add_collection(segs)
        for pose in cut["pose"]:
            axes[2].fill(*_patch_outline(pose).T, fill=False, ec=color, lw=0.6)
        axes[2].annotate(label, xy[0], xytext=(4, 4), textcoords="offset points", fontsize=8,
                         color=color)
        axes[2].plot(*xy[0], "o", color=color, mec="black")
    axes[0].axhline(5.0, color="gray", lw=0.8, ls="--")
    axes[0].set_xlabel("time [s]")
    axes[0].set_ylabel("speed [m/s] (solid)")
    ax_h.set_ylabel("chassis height [m] (dotted)")
    axes[0].legend(fontsize=8, loc="lower left")
    axes[1].set_xlabel("time [s]")
    axes[1].set_ylabel("L(t)")
    axes[1].set_ylim(-0.02, 1.05)
    axes[1].set_title("L(t); dots: patches cut at t_P with label L(t_P)")
    rgb = np.where(bev.observed[..., None], np.clip(bev.rgb, 0, 1), 0.85)
    axes[2].imshow(rgb, origin="lower", extent=bev.grid.extent)
    pts = np.concatenate(xy_all)
    margin = 12.0
    x0, x1, y0, y1 = bev.grid.extent
    axes[2].set_xlim(max(x0, pts[:, 0].min() - margin), min(x1, pts[:, 0].max() + margin))
    axes[2].set_ylim(max(y0, pts[:, 1].min() - margin), min(y1, pts[:, 1].max() + margin))
    axes[2].set_aspect("equal")
    axes[2].set_xlabel("x [m]")
    axes[2].set_ylabel("y [m]")
    axes[2].set_title("paths coloured by L (start: dot), patch outlines")
    fig.colorbar(plt.cm.ScalarMappable(cmap="RdYlGn", norm=plt.Normalize(0, 1)), ax=axes[2],
                 shrink=0.85, label="L")
    return fig


def dataset_table(ds) -> str:
    """A Markdown table of a :class:`~dgt_lib.dataset.PatchDataset` per vehicle: runs,
    patches (train / val / test), patches per run, mean L and the share of L < 0.5."""
    from dgt_lib.dataset import SPLIT_NAMES

    lines = ["| vehicle | runs | patches | " + " / ".join(SPLIT_NAMES)
             + " | patches per run | mean L | L < 0.5 |", "|---" * 7 + "|"]
    for v, name in enumerate(VEHICLES):
        sel = ds.vehicle == v
        n = int(sel.sum())
        runs = len(np.unique(ds.trajectory[sel]))
        parts = " / ".join(str(int(np.sum(sel & (ds.split == s))))
                           for s in range(len(SPLIT_NAMES)))
        if n:
            labels = ds.labels[sel]
            stats = f"{labels.mean():.2f} | {np.mean(labels < 0.5):.0%}"
        else:
            stats = "– | –"
        per_run = f"{n / runs:.1f}" if runs else "–"
        lines.append(f"| {name} | {runs} | {n} | {parts} | {per_run} | {stats} |")
    return "\n".join(lines)


def plot_dataset_counts(ds, paper: Mapping[str, tuple[int, int]] = PAPER_DATASET):
    """The data imbalance: patches per vehicle stacked by split (left) and each
    vehicle's share of all patches, ours against the paper's (right)."""
    from dgt_lib.dataset import SPLIT_NAMES

    fig, axes = plt.subplots(1, 2, figsize=(12, 3.8), constrained_layout=True)
    y = np.arange(len(VEHICLES))
    left = np.zeros(len(VEHICLES))
    for s, sname in enumerate(SPLIT_NAMES):
        n = np.array([np.sum((ds.vehicle == v) & (ds.split == s)) for v in range(len(VEHICLES))])
        axes[0].barh(y, n, left=left, label=sname, color=f"C{s}")
        left += n
    axes[0].set_yticks(y, VEHICLES)
    axes[0].invert_yaxis()
    axes[0].set_xlabel("patches")
    axes[0].set_xlim(0, 1.3 * max(left.max(), 1))
    axes[0].legend(loc="lower right")
    axes[0].set_title(f"{len(ds)} patches by vehicle and split")
    ours = np.array([np.sum(ds.vehicle == v) for v in range(len(VEHICLES))], np.float64)
    theirs = np.array([paper[name][0] for name in VEHICLES], np.float64)
    h = 0.38
    axes[1].barh(y - h / 2, ours / max(ours.sum(), 1), h, label="this dataset", color="0.35")
    axes[1].barh(y + h / 2, theirs / theirs.sum(), h, label="paper", color="0.75")
    axes[1].set_yticks(y, VEHICLES)
    axes[1].invert_yaxis()
    axes[1].set_xlabel("share of all patches")
    axes[1].legend()
    axes[1].set_title("imbalance: share of patches per vehicle")
    return fig


def plot_label_histograms(ds, bins: int = 20):
    """Histogram of the labels L of each vehicle (one panel each, counts)."""
    fig, axes = plt.subplots(1, len(VEHICLES), figsize=(4 * len(VEHICLES), 3.2),
                             constrained_layout=True, sharex=True)
    for v, (ax, name) in enumerate(zip(axes, VEHICLES, strict=True)):
        labels = ds.labels[ds.vehicle == v]
        ax.hist(labels, bins=np.linspace(0, 1, bins + 1), color=VEHICLE_COLORS[name])
        mean = f", mean {labels.mean():.2f}" if labels.size else ""
        ax.set_title(f"{name}: n = {labels.size}{mean}")
        ax.set_xlabel("locomotion L")
    axes[0].set_ylabel("patches")
    return fig


def gallery_indices(labels: np.ndarray, vehicle: np.ndarray, per_vehicle: int = 4
                    ) -> dict[str, np.ndarray]:
    """Indices of up to ``per_vehicle`` samples of each vehicle spanning its label range:
    the samples at evenly spaced label quantiles (lowest L first, highest last),
    without repeats. labels: (N,); vehicle: (N,) head indices."""
    if per_vehicle < 1:
        raise ValueError(f"per_vehicle must be ≥ 1, got {per_vehicle}")
    labels, vehicle = np.asarray(labels), np.asarray(vehicle)
    out = {}
    for v, name in enumerate(VEHICLES):
        idx = np.flatnonzero(vehicle == v)
        order = idx[np.argsort(labels[idx], kind="stable")]
        if len(order) == 0:
            out[name] = order
            continue
        picks = np.rint(np.linspace(0, len(order) - 1, min(per_vehicle, len(order))))
        out[name] = order[np.unique(picks.astype(int))]
    return out


def plot_patch_gallery(ds, per_vehicle: int = 4):
    """A few patches of every vehicle, lowest to highest label (:func:`gallery_indices`):
    RGB and H̄ relative to the patch's centre height [m] side by side, forward = up
    (row 0 of a patch is the row the vehicle drives toward; its left is on the left).
    Unobserved cells are grey."""
    from dgt_lib.bev import HEIGHT
    from dgt_lib.patches import PATCH_COLS, PATCH_ROWS

    picks = gallery_indices(ds.labels, ds.vehicle, per_vehicle)
    # The vehicle's centre lies between the two middle rows, on the middle column.
    centre = (slice(PATCH_ROWS // 2 - 1, PATCH_ROWS // 2 + 1), PATCH_COLS // 2)
    rel = {}
    for i in np.concatenate(list(picks.values())):
        h = ds.patches[i, HEIGHT].astype(np.float64)
        obs = ds.observed[i]
        under = obs[centre]
        if under.any():
            ref = h[centre][under].mean()
        else:
            ref = h[obs].mean() if obs.any() else 0.0
        rel[i] = np.ma.masked_array(h - ref, mask=~obs)
    shown = np.ma.concatenate([r.ravel() for r in rel.values()]) if rel else np.ma.zeros(0)
    values = np.abs(shown.compressed())  # trees would dominate a max: use the 98th percentile
    lim = max(float(np.percentile(values, 98)) if values.size else 0.0, 0.1)
    fig, axes = plt.subplots(len(VEHICLES), 2 * per_vehicle,
                             figsize=(1.3 * 2 * per_vehicle, 2.9 * len(VEHICLES)),
                             constrained_layout=True, squeeze=False)
    cm = plt.get_cmap("coolwarm").copy()
    cm.set_bad("0.8")
    im = None
    for row, name in zip(axes, VEHICLES, strict=True):
        for ax in row:
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_frame_on(False)
        row[0].set_ylabel(name, fontsize=11)
        for k, i in enumerate(picks[name]):
            obs = ds.observed[i][..., None]
            rgb = np.where(obs, np.clip(np.moveaxis(ds.patches[i, :3].astype(np.float32), 0,
                                                    -1), 0, 1), 0.8)
            row[2 * k].imshow(rgb)
            row[2 * k].set_title(f"L = {ds.labels[i]:.2f}\nRGB", fontsize=8)
            im = row[2 * k + 1].imshow(rel[i], cmap=cm, vmin=-lim, vmax=lim)
            row[2 * k + 1].set_title("\nH̄ − centre", fontsize=8)
            row[2 * k].annotate("", xy=(-1.2, 2), xytext=(-1.2, 8), annotation_clip=False,
                                arrowprops={"arrowstyle": "->", "color": "black"})
    if im is not None:
        fig.colorbar(im, ax=axes, shrink=0.5, label="H̄ relative to the centre [m]",
                     location="right", extend="both")
    fig.suptitle("patches from lowest to highest L; arrow = driving direction (forward = up)")
    return fig


def binned_mean(x: np.ndarray, y: np.ndarray, edges: np.ndarray, min_count: int = 1
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean of ``y`` in bins of ``x``.

    x, y: (N,); edges: (B + 1,) increasing bin edges (a value equal to the last edge
    falls in the last bin; values outside are ignored). Returns the bin centres (B,),
    means (B,), standard errors of the mean (B,; 0 for a single sample) and counts (B,);
    mean and standard error are NaN where a bin has fewer than ``min_count`` samples.
    """
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    edges = np.asarray(edges, np.float64)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"x and y must be (N,) of the same length, got {x.shape}, {y.shape}")
    if edges.ndim != 1 or len(edges) < 2 or np.any(np.diff(edges) <= 0):
        raise ValueError("edges must be a strictly increasing (B + 1,) array with B ≥ 1")
    b = len(edges) - 1
    idx = np.searchsorted(edges, x, side="right") - 1
    idx[x == edges[-1]] = b - 1
    ok = (idx >= 0) & (idx < b)
    count = np.bincount(idx[ok], minlength=b).astype(np.int64)
    s1 = np.bincount(idx[ok], weights=y[ok], minlength=b)
    s2 = np.bincount(idx[ok], weights=y[ok] ** 2, minlength=b)
    enough = (count >= max(min_count, 1))
    n = np.maximum(count, 1)
    mean = np.where(enough, s1 / n, np.nan)
    var = np.where(count > 1, (s2 - n * (s1 / n) ** 2) / np.maximum(count - 1, 1), 0.0)
    sem = np.where(enough, np.sqrt(np.maximum(var, 0.0) / n), np.nan)
    return 0.5 * (edges[1:] + edges[:-1]), mean, sem, count


def plot_label_vs_slope(labels: np.ndarray, vehicle: np.ndarray, slope_deg: np.ndarray,
                        edges: np.ndarray | None = None, min_count: int = 3):
    """Directional evidence: label L against the patch's forward slope [deg]
    (positive = uphill in the driving direction), one panel per vehicle: every
    patch (dots) and the binned mean ± standard error (:func:`binned_mean`, bins
    with at least ``min_count`` patches), with the vehicle's torque-limited
    climbing grade (dotted)."""
    edges = np.arange(-30.0, 30.1, 4.0) if edges is None else np.asarray(edges)
    fig, axes = plt.subplots(1, len(VEHICLES), figsize=(4.2 * len(VEHICLES), 3.6),
                             constrained_layout=True, sharey=True)
    for v, (ax, name) in enumerate(zip(axes, VEHICLES, strict=True)):
        sel = np.asarray(vehicle) == v
        x, y = np.asarray(slope_deg)[sel], np.asarray(labels)[sel]
        color = VEHICLE_COLORS[name]
        ax.scatter(x, y, s=6, alpha=0.25, color=color, linewidths=0)
        c, m, se, _ = binned_mean(x, y, edges, min_count)
        ax.errorbar(c, m, yerr=se, color="black", marker="o", ms=4, capsize=2,
                    label=f"mean per {edges[1] - edges[0]:g}° bin")
        ax.axvline(0.0, color="gray", lw=0.8)
        climb = get_vehicle(name).max_climb_deg
        ax.axvline(climb, color="gray", ls=":", label=f"max climb {climb:.0f}°")
        ax.set_xlim(edges[0], edges[-1])
        ax.set_title(f"{name} (n = {int(sel.sum())})")
        ax.set_xlabel("forward slope [deg]  (← downhill | uphill →)")
        ax.legend(fontsize=7, loc="lower left")
    axes[0].set_ylabel("locomotion L")
    axes[0].set_ylim(-0.02, 1.05)
    return fig


def directional_table(labels: np.ndarray, vehicle: np.ndarray, slope_deg: np.ndarray,
                      threshold_deg: float = 8.0) -> str:
    """A Markdown table of the mean label per vehicle on downhill (slope < −t), level
    (|slope| ≤ t) and uphill (slope > t) patches, t = ``threshold_deg``, with the
    patch counts, and the uphill − downhill difference."""
    if not threshold_deg >= 0:
        raise ValueError(f"threshold_deg must be ≥ 0, got {threshold_deg}")
    labels, vehicle, slope = (np.asarray(a) for a in (labels, vehicle, slope_deg))
    t = threshold_deg
    head = (f"| vehicle | downhill (< −{t:g}°) | level | uphill (> {t:g}°) "
            "| uphill − downhill |")
    lines = [head, "|---|---|---|---|---|"]
    for v, name in enumerate(VEHICLES):
        sel = vehicle == v
        means = []
        cells = []
        for mask in (slope < -t, np.abs(slope) <= t, slope > t):
            m = sel & mask
            mean = float(labels[m].mean()) if m.any() else math.nan
            means.append(mean)
            cells.append(f"{mean:.2f} (n = {int(m.sum())})" if m.any() else "– (n = 0)")
        diff = means[2] - means[0]
        cells.append(f"{diff:+.2f}" if math.isfinite(diff) else "–")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- planner
PRIMITIVES = ("straight", "left", "right")
PRIMITIVE_COLORS = {"straight": "tab:blue", "left": "tab:green", "right": "tab:red"}
PLAN_COLORS = ("crimson", "black", "darkviolet", "white", "gold", "saddlebrown", "magenta")
"""Path colours of :func:`plot_plans` (distinct from the route colours)."""


def primitive_lookups(pose, min_turn_radius_m: float, grid, n_headings: int, *,
                      step_m: float = 1.6, substep_m: float = 0.2) -> dict[str, dict]:
    """The three Hybrid A* primitives from ``pose`` (x, y, θ) [m, m, rad] and the
    costmap layer each one is priced in, computed as :class:`planner.HybridAStar` does.

    Returns {"straight" | "left" | "right": {"curvature" κ [1/m] (left > 0),
    "substeps" (n, 3) poses every ≤ ``substep_m`` along the arc (the collision
    checks; the last is the successor), "cell" and "next_cell" (row, col) of the pose
    and of the successor, "d_cell" (Δrow, Δcol), "theta" θ' = atan2(Δrow, Δcol) [rad]
    (None when the cell does not change) and "k" k* = argmin_k |θ_k − θ'| (the bin of
    the arc's mid heading when the cell does not change)}.
    """
    from dgt_lib.geometry import nearest_heading_bin
    from dgt_lib.planner import arc_poses, travel_heading_bin

    if not min_turn_radius_m > 0:
        raise ValueError(f"min_turn_radius_m must be > 0, got {min_turn_radius_m}")
    n_sub = math.ceil(step_m / substep_m)
    arc_lengths = step_m * np.arange(1, n_sub + 1) / n_sub
    x, y, theta = (float(v) for v in pose)
    row, col = (int(v) for v in grid.xy_to_cell(x, y))
    out = {}
    for name, kappa in zip(PRIMITIVES, (0.0, 1.0 / min_turn_radius_m, -1.0 / min_turn_radius_m),
                           strict=True):
        sub = arc_poses((x, y, theta), kappa, arc_lengths)
        r1, c1 = (int(v) for v in grid.xy_to_cell(sub[-1, 0], sub[-1, 1]))
        d = (r1 - row, c1 - col)
        if d == (0, 0):
            th, k = None, int(nearest_heading_bin(theta + kappa * step_m / 2, n_headings))
        else:
            th, k = math.atan2(*d), int(travel_heading_bin(*d, n_headings))
        out[name] = {"curvature": kappa, "substeps": sub, "cell": (row, col),
                     "next_cell": (r1, c1), "d_cell": d, "theta": th, "k": k}
    return out


def plot_motion_primitives(pose, min_turn_radius_m: float, grid, n_headings: int,
                           footprint: tuple[float, float], *, step_m: float = 1.6,
                           substep_m: float = 0.2, title: str = ""):
    """The paper's planning figure for one expansion: left, the three arcs from ``pose``
    at r_min over the grid cells, their collision sub-steps, the footprint circles at
    the end of the straight arc, and the cell move (Δrow, Δcol) each successor is priced
    by; right, the K heading bins θ_k with each move's θ' and the layer k* it reads.
    Returns the figure."""
    from matplotlib.patches import Circle, Rectangle

    from dgt_lib.geometry import heading_bins
    from dgt_lib.planner import arc_poses, footprint_circles

    look = primitive_lookups(pose, min_turn_radius_m, grid, n_headings, step_m=step_m,
                             substep_m=substep_m)
    fig, (ax, ax_k) = plt.subplots(1, 2, figsize=(13, 6),
                                   gridspec_kw={"width_ratios": [1.4, 1]})
    x, y, th = (float(v) for v in pose)
    res = grid.resolution
    span = step_m + 0.5 * footprint[0] + 0.6
    ox, oy = grid.origin_xy
    (r_lo, r_hi), (c_lo, c_hi) = grid.xy_to_cell([x - span, x + span], [y - span, y + span])
    for r in range(int(r_lo), int(r_hi) + 2):
        ax.axhline(oy + r * res, color="0.85", lw=0.6, zorder=0)
    for c in range(int(c_lo), int(c_hi) + 2):
        ax.axvline(ox + c * res, color="0.85", lw=0.6, zorder=0)
    r0, c0 = look["straight"]["cell"]
    ax.add_patch(Rectangle((ox + c0 * res, oy + r0 * res), res, res, color="0.6", zorder=1))
    dense = np.linspace(0, step_m, 50)
    for name, item in look.items():
        color = PRIMITIVE_COLORS[name]
        arc = arc_poses(pose, item["curvature"], dense)
        ax.plot(arc[:, 0], arc[:, 1], color=color, lw=2, zorder=3)
        sub = item["substeps"]
        ax.plot(sub[:, 0], sub[:, 1], "o", color=color, ms=3, zorder=4)
        r1, c1 = item["next_cell"]
        ax.add_patch(Rectangle((ox + c1 * res, oy + r1 * res), res, res, fill=False,
                               ec=color, lw=2, zorder=2))
        theta = "—" if item["theta"] is None else f"{math.degrees(item['theta']):.0f}°"
        ax.annotate("", xy=(ox + (c1 + 0.5) * res, oy + (r1 + 0.5) * res),
                    xytext=(ox + (c0 + 0.5) * res, oy + (r0 + 0.5) * res),
                    arrowprops={"arrowstyle": "->", "color": color, "ls": ":"}, zorder=5)
        ax.plot([], [], color=color, lw=2,
                label=f"{name}: Δ(row, col) = {item['d_cell']}, θ' = {theta}, k* = {item['k']}")
    offsets, radius = footprint_circles(*footprint)
    end = look["straight"]["substeps"][-1]
    for o in offsets:
        ax.add_patch(Circle((end[0] + o * math.cos(end[2]), end[1] + o * math.sin(end[2])),
                            radius, fill=False, ls="--", color="0.3", lw=0.8, zorder=2))
    ax.plot([], [], "--", color="0.3", lw=0.8,
            label="footprint circles at the straight successor (collision check)")
    length, width = footprint
    corner = np.array([end[0], end[1]]) + np.array(
        [[math.cos(end[2]), -math.sin(end[2])], [math.sin(end[2]), math.cos(end[2])]]
    ) @ np.array([-length / 2, -width / 2])
    ax.add_patch(Rectangle(tuple(corner), length, width, angle=math.degrees(end[2]),
                           fill=False, color="0.3", lw=1.2, zorder=2))
    ax.annotate("", xy=(x + 0.5 * math.cos(th), y + 0.5 * math.sin(th)), xytext=(x, y),
                arrowprops={"arrowstyle": "-|>", "color": "k"}, zorder=6)
    ax.set_xlim(x - span, x + span)
    ax.set_ylim(y - span, y + span)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(fontsize=8, loc="lower left")
    ax.set_title(title or f"primitives from θ = {math.degrees(th):.0f}°: s = {step_m} m, "
                 f"r_min = {min_turn_radius_m:.2f} m, cells {res} m")
    bins = heading_bins(n_headings)
    ax_k.plot(np.cos(np.linspace(0, 2 * np.pi, 200)), np.sin(np.linspace(0, 2 * np.pi, 200)),
              color="0.8")
    used = {item["k"] for item in look.values()}
    for k, b in enumerate(bins):
        ax_k.plot([0, math.cos(b)], [0, math.sin(b)], color="k" if k in used else "0.75",
                  lw=2 if k in used else 1)
        ax_k.annotate(f"k={k}\n{math.degrees(b):.0f}°", (1.18 * math.cos(b), 1.18 * math.sin(b)),
                      ha="center", va="center", fontsize=8)
    for name, item in look.items():
        if item["theta"] is not None:
            t = item["theta"]
            ax_k.annotate("", xy=(0.8 * math.cos(t), 0.8 * math.sin(t)), xytext=(0, 0),
                          arrowprops={"arrowstyle": "->", "color": PRIMITIVE_COLORS[name],
                                      "lw": 2})
    ax_k.set_xlim(-1.45, 1.45)
    ax_k.set_ylim(-1.45, 1.45)
    ax_k.set_aspect("equal")
    ax_k.axis("off")
    ax_k.set_title("layers θ_k (bold: read by an arc); arrows: θ'")
    fig.tight_layout()
    return fig


def plot_cost_amplification(betas: Sequence[float] = (0.0, 10.0, 50.0, 150.0), ax=None):
    """C' = C(1 + βC) against C ∈ [0, 1] for each β (log y axis). Returns the figure."""
    from dgt_lib.planner import amplified_cost

    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4))
    c = np.linspace(0.0, 1.0, 201)
    for beta in betas:
        ax.plot(c, 1.0 + amplified_cost(c, beta), label=f"β = {beta:g}")
    ax.set_yscale("log")
    ax.set_xlabel("cost C")
    ax.set_ylabel("edge cost per metre, 1 + C' = 1 + C(1 + βC)")
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    return ax.figure


def plan_table(results: Mapping[str, object]) -> str:
    """Markdown table of :class:`planner.PlanResult` s by name: success, expansions,
    time [s], cost Σ g and length [m] (— where the plan failed)."""
    rows = ["| | found | expansions | time [s] | cost | length [m] |",
            "|---|---|---:|---:|---:|---:|"]
    for name, r in results.items():
        cost, length = (f"{r.cost:.1f}", f"{r.length_m:.1f}") if r.success else ("—", "—")
        rows.append(f"| {name} | {'yes' if r.success else 'no'} | {r.expansions} | "
                    f"{r.time_s:.2f} | {cost} | {length} |")
    return "\n".join(rows)


def plot_plans(world: World, plans: Mapping[str, object], ax=None, *, background=None,
               title: str = "", expanded: bool = False):
    """Planned paths (name → :class:`planner.PlanResult`) over the hill-shaded heights (or
    a (H, W) ``background`` in [0, 1], e.g. one costmap layer), with the world's routes
    and landmarks; ``expanded`` also scatters each plan's expanded nodes. Returns the
    figure."""
    if ax is None:
        _, ax = plt.subplots(figsize=(6.5, 6))
    if background is None:
        shade = LightSource(azdeg=315, altdeg=45).hillshade(
            world.heights.astype(np.float64), vert_exag=2.0, dx=world.resolution,
            dy=world.resolution)
        if not expanded:  # expanded nodes show better over grey shading alone
            ax.imshow(world.heights, origin="lower", extent=world.extent, cmap="terrain")
        ax.imshow(shade, origin="lower", extent=world.extent, cmap="gray",
                  alpha=1.0 if expanded else 0.35)
    else:
        ax.imshow(background, origin="lower", extent=world.extent, cmap="magma", vmin=0, vmax=1)
    _overlay(ax, world, trees=False, labels=False)
    widths = np.linspace(3.5, 1.5, max(2, len(plans)))  # wide first: overlapping paths show
    for i, (name, r) in enumerate(plans.items()):
        color = PLAN_COLORS[i % len(PLAN_COLORS)]
        if expanded and len(r.expanded_xy):
            ax.scatter(*r.expanded_xy.T, s=2, color=color, alpha=0.4, lw=0)
        if r.success:
            ax.plot(r.path[:, 0], r.path[:, 1], color=color, lw=widths[i], label=name)
            ax.plot(*r.path[0, :2], "o", color=color, mec="k")
            ax.plot(*r.path[-1, :2], "*", color=color, mec="k", ms=12)
        else:
            ax.plot([], [], color=color, ls=":", label=f"{name} (no path)")
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title(title)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return ax.figure


# ----------------------------------------------------------------------------- experiments
METHOD_COLORS = {"dgt": "tab:blue", "isotropic": "tab:cyan", "single-task": "tab:purple",
                 "slope": "tab:red", "binary": "tab:gray"}
"""Line colours of the compared methods (the paper's figure uses blue for DGT-Map, red for
slope-based)."""


def plot_queries(ax, queries) -> None:
    """Start poses (arrows) and goals (stars) of experiment queries on a world figure."""
    for q in queries:
        x, y, yaw = q.start
        ax.arrow(x, y, 4 * np.cos(yaw), 4 * np.sin(yaw), width=0.6, color="lime")
        ax.plot(*q.goal, "*", color="yellow", ms=10, mec="k")


def plot_planned_paths(ax, world: World, maps, result, label: str, index: int | None = None):
    """Every method's planned path for one query (the first with ``label``, or trial
    ``index``) over the terrain and occupancy; success ✓ / failure ✗ in the legend."""
    ax.imshow(world.heights, origin="lower", extent=world.grid.extent, cmap="terrain")
    occ = np.ma.masked_equal(maps.occupancy, 0)
    ax.imshow(occ, origin="lower", extent=maps.grid.extent, cmap="gray_r", vmin=0, vmax=2,
              alpha=0.5)
    picked = [r for r in result.results if r.task.query.label == label
              and (index is None or r.task.index == index)]
    if index is None and picked:
        first = picked[0].task.index
        picked = [r for r in picked if r.task.index == first]
    for r in picked:
        mark = "✓" if r.outcome.success else f"✗ {r.outcome.reason}"
        name = f"{r.task.method} ({r.route or 'no path'}) {mark}"
        if len(r.path):
            ax.plot(r.path[:, 0], r.path[:, 1], color=METHOD_COLORS[r.task.method], lw=2,
                    label=name)
        else:
            ax.plot([], [], color=METHOD_COLORS[r.task.method], label=name)
        if len(r.trajectory):
            ax.plot(r.trajectory[:, 1], r.trajectory[:, 2], ":", color=METHOD_COLORS[r.task.method],
                    lw=1)
    if picked:
        q = picked[0].task.query
        plot_queries(ax, [q])
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(f"{label}: planned (solid) and driven (dotted)")


def plot_trial_speeds(result, label: str | None = None):
    """Speed [m/s] against time of the executed trials, one panel per method."""
    methods = [m for m in METHOD_COLORS if any(r.task.method == m for r in result.results)]
    fig, axes = plt.subplots(1, len(methods), figsize=(4 * len(methods), 3.2), sharey=True,
                             squeeze=False)
    for ax, m in zip(axes[0], methods, strict=True):
        for r in result.results:
            if r.task.method == m and (label is None or r.task.query.label == label) \
                    and len(r.trajectory):
                ax.plot(r.trajectory[:, 0], r.speed, color=METHOD_COLORS[m],
                        alpha=0.9 if r.outcome.success else 0.5,
                        ls="-" if r.outcome.success else "--")
        ax.set_title(m)
        ax.set_xlabel("time [s]")
    axes[0, 0].set_ylabel("speed [m/s] (dashed: failed)")
    fig.tight_layout()
    return fig


def plot_success_rates(result, paper: Mapping | None = None):
    """Success rate per method with Wilson 95 % intervals (bars), the paper's SR as dots."""
    from .outcomes import wilson_interval

    vehicles = sorted({r.task.vehicle for r in result.results})
    fig, axes = plt.subplots(1, len(vehicles), figsize=(6 * len(vehicles), 3.8), squeeze=False)
    keys = {"dgt": "dgt_map", "isotropic": "dgt_map_iso", "single-task": "dgt_map_st",
            "slope": "slope_based", "binary": "binary"}
    for ax, v in zip(axes[0], vehicles, strict=True):
        counts = result.counts(v)
        names = list(counts)
        sr = np.array([100 * k / n for k, n in counts.values()])
        ci = np.array([wilson_interval(k, n) for k, n in counts.values()]) * 100
        x = np.arange(len(names))
        ax.bar(x, sr, color=[METHOD_COLORS[m] for m in names],
               yerr=[sr - ci[:, 0], ci[:, 1] - sr], capsize=4, label="ours (Wilson 95 %)")
        if paper and v in paper:
            p = paper[v]
            ps = [100 * p.k[keys[m]] / p.n if keys[m] in p.k else np.nan for m in names]
            ax.plot(x, ps, "ko", label=f"paper (n = {p.n})")
        ax.set_xticks(x, names, rotation=20)
        ax.set_ylim(0, 105)
        ax.set_ylabel("success rate [%]")
        ax.set_title(f"{result.name}: {v}, n = {next(iter(counts.values()))[1]}")
        ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


# ------------------------------------------------------------------------- training (notebook 03)
# The network's parts and shapes, the masked loss's gradients, learning curves, multi-task
# against single-task test errors, predictions on chosen patches, and the width trade-off.
TRAINING_COLORS = {"multi-task": METHOD_COLORS["dgt"], "single-task": METHOD_COLORS["single-task"]}
"""Colours of the multi-task model and the single-task models (as in the experiments)."""


def parameter_table(model) -> str:
    """A Markdown table of a :class:`~dgt_lib.model.DGTNet`'s trainable parameters per
    part: the RGB and height ResNet-18 branches, the FC layer after the concatenation,
    the vehicle heads, and the total (with each part's share)."""
    from dgt_lib.model import count_parameters

    parts = {"RGB branch (ResNet-18)": model.rgb, "height branch (ResNet-18)": model.height,
             "FC + ReLU after the concatenation": model.fc,
             f"{len(model.vehicles)} vehicle heads (linear + sigmoid)": model.vehicle_heads}
    total = count_parameters(model)
    lines = ["| part | parameters | share |", "|---|---:|---:|"]
    for name, module in parts.items():
        n = count_parameters(module)
        lines.append(f"| {name} | {n:,} | {n / total:.1%} |")
    lines.append(f"| **total** | **{total:,}** | 100% |")
    return "\n".join(lines)


def shape_trace(model, x) -> list[tuple[str, tuple[int, ...]]]:
    """The tensor shapes through a DGTNet for patches ``x`` (B, 6, 22, 7), in the order
    they are computed: (stage, shape) for the input, each branch's input, stem
    convolution, max-pool, four ResNet stages and pooled embedding, the concatenation,
    the shared embedding z and the heads' output. Runs once in eval mode, no gradients."""
    import torch

    trace: list[tuple[str, tuple[int, ...]]] = [("input patches (R, G, B, H̄, σ_H, ‖∇H̄‖)",
                                                 tuple(x.shape))]
    steps = {"conv1": "conv 7×7 /2", "maxpool": "max-pool 3×3 /2", "layer1": "layer1",
             "layer2": "layer2 /2", "layer3": "layer3 /2", "layer4": "layer4 /2",
             "avgpool": "global average pool"}

    def after(name):
        return lambda module, args, out: trace.append((name, tuple(out.shape)))

    def before(name):
        return lambda module, args: trace.append((name, tuple(args[0].shape)))

    hooks = []
    for branch in ("rgb", "height"):
        net = getattr(model, branch)
        hooks.append(net.register_forward_pre_hook(before(f"{branch}: input channels")))
        hooks += [getattr(net, part).register_forward_hook(after(f"{branch}: {label}"))
                  for part, label in steps.items()]
    hooks.append(model.fc.register_forward_pre_hook(before("concatenation")))
    hooks.append(model.fc.register_forward_hook(after("shared embedding z (FC + ReLU)")))
    was_training = model.training
    model.eval()
    try:
        with torch.no_grad():
            out = model(x)
    finally:
        for hook in hooks:
            hook.remove()
        model.train(was_training)
    trace.append(("heads + sigmoid: L̂ per vehicle", tuple(out.shape)))
    return trace


def shape_table(trace: Sequence[tuple[str, tuple[int, ...]]]) -> str:
    """:func:`shape_trace` as a Markdown table (stage, shape)."""
    rows = [f"| {name} | {tuple(shape)} |" for name, shape in trace]
    return "\n".join(["| stage | shape |", "|---|---|", *rows])


def head_gradient_norms(model, x, labels, head) -> np.ndarray:
    """L2 norm of the gradient of :func:`~dgt_lib.train.masked_loss` with respect to each
    vehicle head's parameters, for one batch: x (B, 6, 22, 7), labels (B,) and head (B,)
    int64 column of each sample's vehicle. Returns (n_heads,); heads of vehicles not in
    the batch get exactly 0. The model's gradients are cleared before and after."""
    import torch

    from dgt_lib.train import masked_loss

    model.zero_grad(set_to_none=True)
    masked_loss(model(x), labels, head).backward()
    norms = []
    for h in model.vehicle_heads:
        grads = [p.grad for p in h.parameters() if p.grad is not None]
        norms.append(float(torch.sqrt(sum((g**2).sum() for g in grads))) if grads else 0.0)
    model.zero_grad(set_to_none=True)
    return np.array(norms)


def plot_learning_curves(histories: Mapping[str, Sequence[Mapping[str, float]]],
                         best_epochs: Mapping[str, int]):
    """Training and validation loss (mean masked squared error) per epoch, one panel per
    model (``histories[name]`` = ``TrainResult.history``); the kept (best validation)
    epoch ``best_epochs[name]`` is starred."""
    from matplotlib.ticker import MaxNLocator

    n = len(histories)
    fig, axes = plt.subplots(1, n, figsize=(3.4 * n, 3.2), squeeze=False,
                             constrained_layout=True)
    for ax, (name, history) in zip(axes[0], histories.items(), strict=True):
        epoch = [h["epoch"] for h in history]
        ax.plot(epoch, [h["train_loss"] for h in history], "o-", ms=3, label="train")
        ax.plot(epoch, [h["val_loss"] for h in history], "s-", ms=3, label="validation")
        best = next(h for h in history if h["epoch"] == best_epochs[name])
        ax.plot(best["epoch"], best["val_loss"], "*", ms=14, color="gold", mec="k",
                label=f"kept: epoch {best['epoch']}")
        ax.set_title(name)
        ax.set_xlabel("epoch")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.legend(fontsize=7)
    axes[0, 0].set_ylabel("masked MSE")
    return fig


METRIC_NAMES = {"mse": "MSE", "mae": "MAE", "spearman": "Spearman ρ"}


def comparison_table(metrics: Mapping[str, Mapping[str, Mapping[str, float]]],
                     n_train: Mapping[str, int]) -> str:
    """A Markdown table of test errors per vehicle and model.

    metrics: ``{model: {vehicle: {"n", "mse", "mae", "spearman"}}}`` (e.g. ``{"multi-task":
    result.metrics, "single-task": {...}}``); n_train: training patches per vehicle.
    Columns: the vehicle's training and test patches, then MSE, MAE and Spearman ρ of
    every model; with exactly two models a last column gives the second's MSE minus the
    first's (positive: the first is better). A missing value shows as "–".
    """
    models = list(metrics)

    def cell(model: str, vehicle: str, key: str) -> str:
        value = metrics[model].get(vehicle, {}).get(key, float("nan"))
        return "–" if not np.isfinite(value) else f"{value:.{2 if key == 'spearman' else 4}f}"

    head = ["vehicle", "train patches", "test patches"]
    head += [f"{METRIC_NAMES[k]} {m}" for k in METRIC_NAMES for m in models]
    if len(models) == 2:
        head.append(f"MSE {models[1]} − {models[0]}")
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for v in VEHICLES:
        n_test = next((int(metrics[m][v]["n"]) for m in models if v in metrics[m]), 0)
        row = [v, str(n_train.get(v, 0)), str(n_test)]
        row += [cell(m, v, k) for k in METRIC_NAMES for m in models]
        if len(models) == 2:
            a, b = (metrics[m].get(v, {}).get("mse", float("nan")) for m in models)
            row.append("–" if not np.isfinite(b - a) else f"{b - a:+.4f}")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def plot_metric_comparison(metrics: Mapping[str, Mapping[str, Mapping[str, float]]],
                           n_train: Mapping[str, int]):
    """Grouped bars of test MSE, MAE and Spearman ρ per vehicle (x, with its training
    patches), one bar per model (same arguments as :func:`comparison_table`)."""
    models = list(metrics)
    x = np.arange(len(VEHICLES))
    w = 0.8 / len(models)
    fig, axes = plt.subplots(1, len(METRIC_NAMES), figsize=(14, 3.6), constrained_layout=True)
    for ax, (key, label) in zip(axes, METRIC_NAMES.items(), strict=True):
        for k, m in enumerate(models):
            values = np.array([metrics[m].get(v, {}).get(key, np.nan) for v in VEHICLES])
            pos = x + (k - (len(models) - 1) / 2) * w
            ax.bar(pos, np.nan_to_num(values), w, label=m,
                   color=TRAINING_COLORS.get(m, f"C{k}"))
            for p, value in zip(pos, values, strict=True):
                if not np.isfinite(value):
                    ax.text(p, 0, "n/a", ha="center", va="bottom", fontsize=7)
        ax.set_xticks(x, [f"{v}\n({n_train.get(v, 0)} train)" for v in VEHICLES], fontsize=8)
        ax.set_title(f"test {label}" + (" (higher is better)" if key == "spearman"
                                        else " (lower is better)"))
        ax.axhline(0, color="k", lw=0.5)
    axes[0].legend()
    return fig


def own_head_predictions(multitask, single: Mapping[str, object], part
                         ) -> dict[str, np.ndarray]:
    """Each sample's prediction by its own vehicle's head: ``{"multi-task": (N,),
    "single-task": (N,)}`` for the samples of ``part`` (a PatchDataset). ``single`` maps a
    vehicle to its single-task model; samples of a vehicle without one get NaN."""
    from dgt_lib.train import predict

    columns = np.array([multitask.head_index(v) for v in range(len(VEHICLES))])
    multi = predict(multitask, part.patches)[np.arange(len(part)), columns[part.vehicle]]
    solo = np.full(len(part), np.nan, dtype=np.float32)
    for name, model in single.items():
        idx = np.flatnonzero(part.vehicle == VEHICLES.index(name))
        if len(idx):
            solo[idx] = predict(model, part.patches[idx])[:, model.head_index(name)]
    return {"multi-task": multi, "single-task": solo}


def plot_predicted_vs_true(predictions: Mapping[str, np.ndarray], labels: np.ndarray,
                           vehicle: np.ndarray):
    """Predicted against true L, one panel per vehicle, one colour per model
    (``predictions[model]`` (N,), e.g. from :func:`own_head_predictions`; labels (N,),
    vehicle (N,) head indices). The diagonal is a perfect prediction."""
    fig, axes = plt.subplots(1, len(VEHICLES), figsize=(3.6 * len(VEHICLES), 3.8),
                             sharex=True, sharey=True, constrained_layout=True)
    for v, (ax, name) in enumerate(zip(axes, VEHICLES, strict=True)):
        sel = vehicle == v
        ax.plot([0, 1], [0, 1], color="0.6", lw=1)
        for k, (model, pred) in enumerate(predictions.items()):
            ok = sel & np.isfinite(pred)
            if ok.any():
                mse = np.mean((pred[ok] - labels[ok]) ** 2)
                ax.scatter(labels[ok], pred[ok], s=10, alpha=0.5, linewidths=0,
                           color=TRAINING_COLORS.get(model, f"C{k}"),
                           label=f"{model} (MSE {mse:.3f})")
        ax.set_title(f"{name}: {int(sel.sum())} test patches")
        ax.set_xlabel("true L")
        ax.set_xlim(-0.03, 1.03)
        ax.set_ylim(-0.03, 1.03)
        ax.set_aspect("equal")
        if ax.has_data():
            ax.legend(fontsize=7, loc="upper left")
    axes[0].set_ylabel("predicted L̂")
    return fig


def plot_predicted_patches(patches: np.ndarray, observed: np.ndarray, names: Sequence[str],
                           predictions: np.ndarray):
    """Chosen patches with every vehicle's predicted L̂: per patch a column of its RGB,
    its H̄ relative to the height under the vehicle [m] (forward = up) and one bar per
    vehicle. patches (n, 6, 22, 7), observed (n, 22, 7), names (n,), predictions (n, 4)
    in :data:`VEHICLES` order. Each height panel has its own colour scale (± its largest
    |H̄ − centre|, at least 0.1 m), so a 0.7 m ridge shows next to a 9 m tree."""
    from dgt_lib.bev import HEIGHT

    n = len(names)
    fig, axes = plt.subplots(3, n, figsize=(2.6 * n, 8.2), squeeze=False,
                             gridspec_kw={"height_ratios": [3, 3, 2]}, constrained_layout=True)
    cm = plt.get_cmap("coolwarm").copy()
    cm.set_bad("0.8")
    centre = (slice(10, 12), 3)  # the vehicle sits between rows 10 and 11, column 3
    rel = []
    for p, obs in zip(patches, observed, strict=True):
        h = p[HEIGHT].astype(np.float64)
        ref = h[centre][obs[centre]].mean() if obs[centre].any() else h[obs].mean()
        rel.append(np.ma.masked_array(h - ref, mask=~obs))
    for k in range(n):
        rgb = np.clip(np.moveaxis(patches[k, :3].astype(np.float32), 0, -1), 0, 1)
        axes[0, k].imshow(np.where(observed[k][..., None], rgb, 0.8))
        axes[0, k].set_title(names[k], fontsize=9, wrap=True)
        lim = max(float(np.abs(rel[k]).max()), 0.1)
        im = axes[1, k].imshow(rel[k], cmap=cm, vmin=-lim, vmax=lim)
        fig.colorbar(im, ax=axes[1, k], orientation="horizontal", shrink=0.8, pad=0.02,
                     label="H̄ − centre [m]")
        for ax in axes[:2, k]:
            ax.set_xticks([])
            ax.set_yticks([])
        bars = axes[2, k].bar(range(len(VEHICLES)), predictions[k],
                              color=[VEHICLE_COLORS[v] for v in VEHICLES])
        axes[2, k].bar_label(bars, fmt="%.2f", fontsize=7)
        axes[2, k].set_ylim(0, 1.15)
        axes[2, k].set_xticks(range(len(VEHICLES)), VEHICLES, rotation=60, fontsize=7)
    axes[0, 0].set_ylabel("RGB")
    axes[1, 0].set_ylabel("H̄ − centre")
    axes[2, 0].set_ylabel("predicted L̂")
    fig.suptitle("multi-task predictions; the vehicle drives up the page from the centre")
    return fig


def inference_rate(model, patches: np.ndarray, *, repeats: int = 3,
                   batch_size: int = 1024) -> float:
    """Inference speed in patches per second: the best of ``repeats`` timed runs of
    :func:`~dgt_lib.train.predict` over ``patches`` (N, 6, 22, 7), after one warm-up
    batch. Measured on the model's device with torch's current thread count."""
    import time

    from dgt_lib.train import predict

    if repeats < 1 or len(patches) == 0:
        raise ValueError(f"need repeats ≥ 1 and patches, got {repeats} and {len(patches)}")
    predict(model, patches[:batch_size], batch_size)
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        predict(model, patches, batch_size)
        best = min(best, time.perf_counter() - t0)
    return len(patches) / max(best, 1e-9)


def width_tradeoff(dataset, cfg, widths: Sequence[int], *, epochs: int, seed: int = 0,
                   n_patches: int = 4096, progress: bool = True) -> list[dict[str, float]]:
    """Train the multi-task model at each ``width`` for ``epochs`` (else as ``cfg``, a
    TrainConfig) and measure it: one dict per width with ``width``, ``parameters``,
    ``test_mse`` (masked MSE over every vehicle's test patches, each by its own head),
    ``patches_per_s`` (:func:`inference_rate` on ``n_patches`` test patches, repeated to
    that many) and ``train_s`` (seconds of training)."""
    from dataclasses import replace

    from tqdm.auto import tqdm

    from dgt_lib.model import count_parameters
    from dgt_lib.train import train_model

    test = dataset.part("test")
    if len(test) == 0:
        raise ValueError("the dataset has no test patches to score the widths on")
    timing = np.resize(test.patches, (n_patches, *test.patches.shape[1:]))
    rows = []
    for width in tqdm(widths, desc="widths", disable=not progress):
        run = replace(cfg, width=int(width), epochs=int(epochs), patience=None)
        result = train_model(dataset, run, seed=seed, progress=False)
        scores = result.metrics.values()
        n = sum(m["n"] for m in scores)
        rows.append({"width": int(width), "parameters": count_parameters(result.model),
                     "test_mse": sum(m["n"] * m["mse"] for m in scores) / n,
                     "patches_per_s": inference_rate(result.model, timing, repeats=5),
                     "train_s": sum(h["seconds"] for h in result.history)})
    return rows


def tradeoff_table(rows: Sequence[Mapping[str, float]]) -> str:
    """:func:`width_tradeoff` rows as a Markdown table."""
    lines = ["| width | parameters | test MSE | inference [patches/s] | training [s] |",
             "|---:|---:|---:|---:|---:|"]
    lines += [f"| {r['width']} | {r['parameters'] / 1e6:.2f} M | {r['test_mse']:.4f} | "
              f"{r['patches_per_s']:,.0f} | {r['train_s']:.1f} |" for r in rows]
    return "\n".join(lines)


def plot_width_tradeoff(rows: Sequence[Mapping[str, float]], paper_width: int = 64):
    """Test MSE against inference speed, one point per network width (labelled with its
    parameter count); ``paper_width`` (the paper's ResNet-18) is drawn as a star."""
    from matplotlib.ticker import StrMethodFormatter

    fig, ax = plt.subplots(figsize=(6.5, 4), constrained_layout=True)
    for k, r in enumerate(rows):  # labels alternate above and below: neighbours may be close
        paper = r["width"] == paper_width
        ax.scatter(r["patches_per_s"], r["test_mse"], s=160 if paper else 50,
                   marker="*" if paper else "o", color="tab:blue", zorder=2)
        ax.annotate(f"width {r['width']}{' (paper)' if paper else ''}\n"
                    f"{r['parameters'] / 1e6:.2f} M", (r["patches_per_s"], r["test_mse"]),
                    textcoords="offset points", xytext=(6, 6 if k % 2 == 0 else -22),
                    fontsize=8)
    ax.set_xlim(0, 1.3 * max(r["patches_per_s"] for r in rows))
    ax.xaxis.set_major_formatter(StrMethodFormatter("{x:,.0f}"))
    ax.set_xlabel("inference speed [patches/s] (right is faster)")
    ax.set_ylabel("test MSE, all vehicles (lower is better)")
    ax.set_title("network width: accuracy against speed")
    ax.margins(y=0.25)
    return fig
