"""Figures and tables of notebook 02 (locomotion labels).

Paper: Methodology → Locomotion, Self-Supervised Label Generation, Patches, and
Experiments → Dataset.

L against the speed ratio, L(t) along recorded runs with the patches cut from them,
the dataset's counts per vehicle and split against the paper's, label histograms, a
patch gallery (:func:`gallery_indices`) and the directional evidence: L against forward
slope (:func:`binned_mean`, :func:`directional_table`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import matplotlib.pyplot as plt
import numpy as np

from dgt_lib.core.config import VEHICLES
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.viz.common import VEHICLE_COLORS

PAPER_DATASET: dict[str, tuple[int, int]] = {
    "jeep": (30_000, 400), "vw_van": (10_000, 400), "mercedes_van": (10_000, 300),
    "carla_cola": (2_000, 200),
}
"""(patches, trajectories) per vehicle as the paper reports them (Experiments → Dataset)."""


def plot_locomotion_curve():
    """L (solid) and the cost C = 1 − L (dashed) against the speed ratio
    ‖Δx‖ / (u·Δt) from standing still (0) to twice the commanded speed (2), at the
    collection's speed u and the paper's σ, computed by
    :func:`dgt_lib.perception.locomotion.locomotion`."""
    from dgt_lib.perception.locomotion import SIGMA, TARGET_SPEED_MPS, locomotion

    u, sigma = TARGET_SPEED_MPS, SIGMA
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
    from dgt_lib.perception.patches import PATCH_LENGTH_M, PATCH_WIDTH_M, body_to_world

    f, w = 0.5 * PATCH_LENGTH_M, 0.5 * PATCH_WIDTH_M
    corners = np.array([[f, w], [f, -w], [-f, -w], [-f, w]])
    x, y = body_to_world(np.asarray(pose, np.float64)[None], corners)
    return np.stack([x[0], y[0]], axis=1)


def plot_run_labels(runs: Mapping[str, object], bev, config=None):
    """Locomotion along recorded runs (:class:`dgt_lib.perception.episodes.Episode`), one
    colour each.

    Left: speed [m/s] (solid) and chassis height [m] (dotted) against time.
    Middle: L(t) from the sliding window (:func:`dgt_lib.perception.locomotion.locomotion_signal`)
    with the patches the dataset cuts from the run (dots at (t_P, L(t_P)),
    :func:`dgt_lib.perception.dataset.episode_patches`). Right: the paths on the BEV map,
    coloured by L, with every patch's 8.8 m × 2.8 m outline.
    """
    from matplotlib.collections import LineCollection

    from dgt_lib.perception.dataset import episode_patches
    from dgt_lib.perception.locomotion import locomotion_signal

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
    """A Markdown table of a :class:`~dgt_lib.perception.dataset.PatchDataset` per vehicle: runs,
    patches (train / val / test), patches per run, mean L and the share of L < 0.5."""
    from dgt_lib.perception.dataset import SPLIT_NAMES

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
    from dgt_lib.perception.dataset import SPLIT_NAMES

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
    from dgt_lib.perception.bev import HEIGHT
    from dgt_lib.perception.patches import PATCH_COLS, PATCH_ROWS

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
