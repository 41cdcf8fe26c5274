"""Real terrain in, maps out: ``dgt plan`` and ``dgt costmap`` on a real DEM.

The DEM ships with matplotlib (a dependency of the kit): ``jacksboro_fault_dem.npz``,
344 × 403 elevations [m] on a 3 arc-second grid (about 74 m east-west × 93 m
north-south) over the Jacksboro fault and Pine Mountain, Tennessee. It is SRTM elevation
data, public domain, added to matplotlib's sample data in matplotlib pull request #3291
(https://github.com/matplotlib/matplotlib/pull/3291). Row 0 is the north edge, as
matplotlib's hillshading examples draw it (Pine Mountain then runs north-east, as it
does).

This script crops the window where Experiment 1 can repeat on real ground — a route
carla_cola climbs beside a slope it can only descend, between the same two points
(:func:`choose_window`) — writes it as a GeoTIFF in EPSG:4326 (longitude, latitude in
degrees: the kit reprojects it to UTM) and prints the two ``dgt plan`` queries, up and
down (:func:`window_queries`). With ``--figure`` it plans both with the profile's models
(the geometry-only DGT-Map: the DEM has no imagery), drives both plans with ``--drive``,
and draws them; ``--publish`` writes the plans' table as a record that docs/usage.md
quotes::

    python examples/real_dem.py                       # writes data/examples/jacksboro.tif
    python examples/real_dem.py --figure docs/figures/jacksboro_plans.png --drive --publish

The walkthrough, with the ``dgt`` commands: docs/usage.md, "A real DEM: the Jacksboro
fault".
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

SAMPLE_NAME = "jacksboro_fault_dem.npz"
EARTH_RADIUS_M = 6_371_008.8
"""Mean Earth radius [m]: cell sizes in metres from degrees (a sphere: within 0.5 %)."""

WINDOW_CELLS = 5
"""Side of the window [DEM cells]: 5 × 5 cells ≈ 370 m × 460 m, 1.1 million height
cells at the kit's 0.4 m (the kit maps at most 4 million)."""

OCCUPIED_DEG = 27.0
"""Ground steeper than this [deg] is an obstacle to every vehicle: τ_s, the occupancy
map's gradient threshold, is 0.51 m/m (27°) in the ``smoke`` profile; a slope carla_cola
only descends has no point steeper."""

DEFAULT_OUT = Path("data/examples/jacksboro.tif")


@dataclass(frozen=True)
class SampleDem:
    """matplotlib's Jacksboro DEM: heights (H, W) [m], row 0 the north edge; the grid's
    north-west corner (``west``, ``north``) and its cell size ``step`` [deg]."""

    heights: np.ndarray
    west: float
    north: float
    step: float

    def cell_size_m(self) -> tuple[float, float]:
        """(east-west, north-south) size of a cell [m] at the grid's middle latitude."""
        lat = np.radians(self.north - self.step * self.heights.shape[0] / 2)
        dy = np.radians(self.step) * EARTH_RADIUS_M
        return float(dy * np.cos(lat)), float(dy)

    def patch_slopes_deg(self) -> tuple[np.ndarray, np.ndarray]:
        """Slopes [deg] of the bilinear patches between four cell centres (what the kit's
        bilinear resampling makes of the DEM), each (H - 1, W - 1): at the patch's centre,
        and its steepest (at one of its corners: the gradient of a bilinear patch varies
        linearly along each axis, so its norm peaks at a corner)."""
        dx, dy = self.cell_size_m()
        z = self.heights.astype(np.float64)
        east = np.diff(z, axis=1) / dx  # (H, W - 1): top and bottom edges of each patch
        north = -np.diff(z, axis=0) / dy  # (H - 1, W): its west and east edges
        h, w = z.shape
        corners = np.stack([np.hypot(east[a:a + h - 1], north[:, b:b + w - 1])
                            for a in (0, 1) for b in (0, 1)])
        centre = np.hypot((east[:-1] + east[1:]) / 2, (north[:, :-1] + north[:, 1:]) / 2)
        return np.degrees(np.arctan(centre)), np.degrees(np.arctan(corners.max(axis=0)))


def load_sample() -> SampleDem:
    """The DEM from matplotlib's sample data (its 'xmin' is the west edge and its 'ymin'
    the north edge: row 0; the cells are square in degrees)."""
    from matplotlib.cbook import get_sample_data

    with np.load(get_sample_data(SAMPLE_NAME, asfileobj=False)) as npz:
        heights = npz["elevation"].astype(np.float32)
        west, north, step = float(npz["xmin"]), float(npz["ymin"]), float(npz["dx"])
        assert float(npz["dy"]) == step and float(npz["ymax"]) < north
    return SampleDem(heights, west, north, step)


@dataclass(frozen=True)
class Window:
    """A window of the DEM and its two landmarks. ``row``, ``col``: its north-west cell;
    ``low``, ``high``: (row, column) of two of its patches (between cell centres, row 0
    north) joined by ground carla_cola climbs, while the straight line between them
    crosses ground it only descends; ``rise_m``: ``high``'s mean height above ``low``'s."""

    row: int
    col: int
    low: tuple[int, int]
    high: tuple[int, int]
    rise_m: float


def choose_window(dem: SampleDem, cells: int = WINDOW_CELLS, climb_deg: float | None = None,
                  occupied_deg: float = OCCUPIED_DEG) -> Window:
    """The ``cells`` × ``cells`` window where Experiment 1 can repeat on real ground: two
    patches joined by a route carla_cola climbs — patches whose steepest point is gentler
    than half its torque-limited climb ``climb_deg`` (11.8° by default), the class
    Experiment 1's Route A (5°) belongs to — while the straight line between them crosses
    a patch it can only descend (its centre steeper than ``climb_deg``, no point steeper
    than ``occupied_deg``). Of all windows and such pairs (the lowest and the highest
    patch of each connected gentle region), the one with the largest rise; ties go to the
    first in row order. Patches are :meth:`SampleDem.patch_slopes_deg`'s: what the kit's
    bilinear resampling makes of the DEM. Windows with a dead-flat patch (SRTM flattens
    lakes to one height) are skipped."""
    from numpy.lib.stride_tricks import sliding_window_view
    from scipy.ndimage import label

    if climb_deg is None:
        from dgt_lib.core.vehicles import get_vehicle

        climb_deg = get_vehicle("carla_cola").max_climb_deg
    centre, steepest = dem.patch_slopes_deg()
    z = dem.heights.astype(np.float64)
    patch_z = (z[:-1, :-1] + z[1:, :-1] + z[:-1, 1:] + z[1:, 1:]) / 4  # mean of its corners
    gentle = steepest < climb_deg / 2
    descend_only = (centre > climb_deg) & (steepest < occupied_deg)
    n = cells - 1  # patches per window side
    windows = sliding_window_view  # each window's patches: (rows, cols, n, n)
    candidates = ((windows(steepest, (n, n)).min(axis=(2, 3)) > 0.0)
                  & windows(descend_only, (n, n)).any(axis=(2, 3))
                  & (windows(gentle, (n, n)).sum(axis=(2, 3)) >= 2))
    best: Window | None = None
    for row, col in np.argwhere(candidates):
        box = np.s_[row:row + n, col:col + n]
        regions, count = label(gentle[box])
        for k in range(1, count + 1):
            cells_k = np.argwhere(regions == k)
            zk = patch_z[box][regions == k]
            low, high = cells_k[zk.argmin()], cells_k[zk.argmax()]
            rise = float(zk.max() - zk.min())
            if (best is None or rise > best.rise_m) and _crosses(descend_only[box], low, high):
                best = Window(int(row), int(col), (int(low[0]), int(low[1])),
                              (int(high[0]), int(high[1])), rise)
    if best is None:
        raise ValueError("no window of the DEM has a gentle route beside a descend-only slope")
    return best


def _crosses(mask: np.ndarray, a: np.ndarray, b: np.ndarray, samples: int = 64) -> bool:
    """Whether the straight line between patch centres ``a`` and ``b`` (row, column)
    passes through a patch of ``mask``."""
    t = np.linspace(0.0, 1.0, samples)
    rows = np.rint(a[0] + t * (b[0] - a[0])).astype(int)
    cols = np.rint(a[1] + t * (b[1] - a[1])).astype(int)
    return bool(mask[rows, cols].any())


def write_window(path: str | Path, dem: SampleDem, row: int, col: int,
                 cells: int = WINDOW_CELLS) -> Path:
    """The window's heights as a one-band GeoTIFF in EPSG:4326 (float32 [m], no no-data
    cells). Returns the path."""
    from dgt_lib.world.dem import import_rasterio

    rasterio = import_rasterio()
    from rasterio.transform import Affine

    window = dem.heights[row:row + cells, col:col + cells]
    transform = Affine(dem.step, 0.0, dem.west + col * dem.step,
                       0.0, -dem.step, dem.north - row * dem.step)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with rasterio.open(path, "w", driver="GTiff", height=cells, width=cells, count=1,
                       dtype="float32", crs="EPSG:4326", transform=transform) as dst:
        dst.write(window, 1)
    return path


Query = tuple[tuple[float, float, float], tuple[float, float]]
"""A ``dgt plan`` query: start (x, y [m], yaw [rad]) and goal (x, y [m]) in the world."""


def window_queries(dem: SampleDem, window: Window, georef) -> tuple[Query, Query]:
    """carla_cola's two queries on the window's world: up from ``window.low``'s centre to
    ``window.high``'s, starting towards it, and back down, starting towards ``low``. In
    metres from the world's south-west corner (``georef``: the world's
    :class:`~dgt_lib.world.dem.Georeference`, which places a longitude and latitude),
    rounded to the metre, as ``dgt plan --start X,Y,YAW --goal X,Y`` takes them."""
    def centre(patch: tuple[int, int]) -> tuple[float, float]:
        # a patch lies between cell centres: its centre is one cell in from its cell's corner
        lon = dem.west + (window.col + patch[1] + 1) * dem.step
        lat = dem.north - (window.row + patch[0] + 1) * dem.step
        x, y = georef.to_local([lon], [lat])
        return float(np.rint(x[0])), float(np.rint(y[0]))

    low, high = centre(window.low), centre(window.high)
    up = float(np.round(np.arctan2(high[1] - low[1], high[0] - low[0]), 4))
    down = float(np.round(np.arctan2(low[1] - high[1], low[0] - high[0]), 4))
    return ((*low, up), high), ((*high, down), low)


PLAN_SETTINGS = {"planner.max_time_s": 120.0, "planner.max_expansions": 2_000_000}
"""The plans' changes to the profile (``dgt plan --set planner.max_time_s=120 --set
planner.max_expansions=2000000``): the way up, round the slope DGT-Map prices high in
every heading that climbs it, takes more expansions on the window's million cells than
the default budget of 200,000, and the time budget counts the 2D relaxation over the whole
map too."""


def plan_both_ways(world_path: Path, queries: tuple[Query, Query], profile: str,
                   vehicle: str = "carla_cola", method: str = "dgt",
                   drive: bool = False) -> list:
    """``dgt plan``'s engine on the window for the two ``queries`` (up, then down:
    :func:`window_queries`) under :data:`PLAN_SETTINGS` (``drive``: each found plan
    driven as ``dgt plan --drive`` drives it): two
    :class:`~dgt_lib.app.query.QueryReport`."""
    from dgt_lib.app.plan_one import plan_query
    from dgt_lib.core.config import get_profile

    prof = get_profile(profile).with_overrides(PLAN_SETTINGS)
    return [plan_query(str(world_path), vehicle, start, goal, method=method, profile=prof,
                       drive=drive) for start, goal in queries]


def plans_table(reports: list) -> dict:
    """The two plans as a record's table: each query's plan and, when driven, how the
    drive ended."""
    from dgt_lib.records.study import table

    rows = []
    for label, r in zip(("up", "down"), reports, strict=True):
        plan, out = r.plan, r.outcome
        found = (f"{plan.length_m:.1f} m, cost {plan.cost:,.1f}" if plan.success
                 else f"not found ({plan.failure})")
        driven = ("not driven" if out is None else
                  f"{out.reason} after {out.duration_s:.1f} s")
        rows.append([label, f"({r.start[0]:g}, {r.start[1]:g}) → ({r.goal[0]:g}, {r.goal[1]:g})",
                     found, f"{plan.expansions:,}", driven])
    return table("carla_cola's DGT-Map plans on the Jacksboro window",
                 ["way", "from → to [m]", "plan", "expansions", "driven"], rows)


def draw(dem: SampleDem, window: Window, world_path: Path, costmap_path: Path,
         reports: list, out: Path, profile: str) -> Path:
    """Left: the whole sample DEM, hill-shaded, and the window. Right: the window as the
    kit's world (heights, 10 m contours; metres from its south-west corner), the
    occupancy read back from the ``dgt costmap`` GeoTIFF's last band, and the plans.
    Saved as a PNG of at most 200 KB."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import rasterio
    from matplotlib.colors import LightSource

    from dgt_lib.app.figures import save_png
    from dgt_lib.app.plan_one import load_world
    from dgt_lib.core.config import get_profile

    shade = LightSource(azdeg=315, altdeg=45)
    fig, ax = plt.subplots(1, 2, figsize=(12, 5.2), gridspec_kw={"width_ratios": [1.1, 1]})
    h, w = dem.heights.shape
    dx, dy = dem.cell_size_m()
    ax[0].imshow(shade.shade(dem.heights.astype(float), plt.cm.gist_earth, dx=dx, dy=dy,
                             blend_mode="overlay"),
                 extent=(dem.west, dem.west + w * dem.step, dem.north - h * dem.step, dem.north),
                 aspect=dy / dx)
    x0, y1 = dem.west + window.col * dem.step, dem.north - window.row * dem.step
    side = WINDOW_CELLS * dem.step
    ax[0].add_patch(plt.Rectangle((x0, y1 - side), side, side, fill=False, color="red", lw=2))
    ax[0].set(title="matplotlib's Jacksboro DEM (SRTM, 3″) and the window",
              xlabel="longitude [°]", ylabel="latitude [°]")
    world, georef = load_world(str(world_path), get_profile(profile))
    image = ax[1].imshow(world.heights, origin="lower", extent=world.extent, cmap="terrain")
    fig.colorbar(image, ax=ax[1], shrink=0.8, label="height [m]")
    levels = np.arange(np.ceil(world.heights.min() / 10) * 10, world.heights.max(), 10.0)
    contours = ax[1].contour(world.heights, levels, origin="lower", extent=world.extent,
                             colors="k", linewidths=0.4)
    ax[1].clabel(contours, levels[::2], fontsize=7)
    with rasterio.open(costmap_path) as src:
        occupancy = src.read(src.count)[::-1]  # back to south row first
    ax[1].imshow(np.ma.masked_equal(occupancy, 0), origin="lower", extent=world.extent,
                 cmap="Reds", vmin=0, vmax=1.5, alpha=0.7)
    for report, color, label in zip(reports, ("magenta", "orange"), ("up", "down"),
                                    strict=True):
        if report.plan.success:
            ax[1].plot(report.plan.path[:, 0], report.plan.path[:, 1], color=color, lw=2,
                       label=f"{label}: {report.plan.length_m:.0f} m")
    (sx, sy, _), (gx, gy) = reports[0].start, reports[0].goal
    ax[1].plot(sx, sy, "ko", ms=6)
    ax[1].plot(gx, gy, "k*", ms=11)
    ax[1].legend(loc="upper right", fontsize=8)
    occupied = f"{int(occupancy.sum()):,} occupied (red)" if occupancy.any() else "none occupied"
    ax[1].set(title=f"the window as a world: {world.heights.shape[1]} × "
                    f"{world.heights.shape[0]} cells, {occupied}",
              xlabel="x east [m]", ylabel="y north [m]")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    return save_png(fig, out, max_bytes=200_000)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="the GeoTIFF to write")
    parser.add_argument("--figure", type=Path, help="also plan on it and draw the plans here")
    parser.add_argument("--profile", default="demo", help="profile of the plans (--figure)")
    parser.add_argument("--drive", action="store_true", help="also drive both plans")
    parser.add_argument("--publish", action="store_true",
                        help="write the plans' table to docs/runs/studies/ (with --figure)")
    args = parser.parse_args(argv)
    dem = load_sample()
    window = choose_window(dem)
    row, col = window.row, window.col
    path = write_window(args.out, dem, row, col)
    dx, dy = dem.cell_size_m()
    print(f"window: rows {row}–{row + WINDOW_CELLS - 1}, columns {col}–{col + WINDOW_CELLS - 1} "
          f"of {dem.heights.shape}, ≈ {WINDOW_CELLS * dx:.0f} m × {WINDOW_CELLS * dy:.0f} m, "
          f"north-west corner {dem.west + col * dem.step:.5f}° E, "
          f"{dem.north - row * dem.step:.5f}° N → {path}")
    from dgt_lib.core.config import get_profile
    from dgt_lib.world.dem import read_dem

    georef = read_dem(path, get_profile(args.profile).worlds.hfield_resolution_m).georef
    queries = window_queries(dem, window, georef)
    print(f"carla_cola's queries, {window.rise_m:.0f} m up and back down:")
    for way, ((x, y, yaw), (gx, gy)) in zip(("up", "down"), queries, strict=True):
        print(f"  {way + ':':<5} dgt plan --world {path} --vehicle carla_cola "
              f"--start {x:g},{y:g},{yaw:g} --goal {gx:g},{gy:g}")
    if args.figure is None:
        return 0
    from dgt_lib.app.costmap_export import export_costmap

    costmap = export_costmap(str(path), "carla_cola", path.with_name(f"{path.stem}_carla_cola.tif"),
                             profile=args.profile)[0]
    reports = plan_both_ways(path, queries, args.profile, drive=args.drive)
    for report in reports:
        print(report.summary())
    print(draw(dem, window, path, costmap, reports, args.figure, args.profile))
    if args.publish:
        from dgt_lib.records.study import publish_study, study_record

        record = study_record("real_dem", args.profile, [get_profile(args.profile).seed],
                              {"plans": plans_table(reports)}, argv=argv,
                              script="examples/real_dem.py")
        print(f"published {publish_study(record)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
