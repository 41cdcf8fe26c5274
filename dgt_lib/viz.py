"""Matplotlib figures of worlds, vehicles, RGB-D frames and premise runs.

Every function returns the matplotlib ``Figure`` (or draws into a given ``ax``),
so notebooks stay one call per picture::

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
