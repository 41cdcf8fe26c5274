"""Costmap accuracy against the ground truth (ours: the paper scores its costmaps only
through closed-loop success, where planning, control and chance add their noise).

Each method's cost C = 1 − L̂ at a sampled cell and heading layer θ_k is compared with the
measured C* = 1 − L* of :mod:`dgt_lib.evaluation.ground_truth` at the same cell and θ_k:

- **MAE** = mean |C − C*| over the measured samples;
- **Spearman ρ** between C and C* (does the map *rank* terrain right? the planner's
  choices depend on the ranking more than on the level);
- **directional contrast**: over the opposite-heading pairs (θ, θ + π) of one cell whose
  ground truth differs by more than 0.3, the mean |C(θ) − C(θ + π)| of the method beside
  the truth's mean |C*(θ) − C*(θ + π)|, and how often the method's difference has the
  truth's sign (the harder direction is the costlier one). An isotropic map has contrast 0.

Samples on cells the occupancy map marks occupied or unobserved are left out: there the
planner never reads the cost. A one-layer map (isotropic, binary) gives every heading the
same cost.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy import stats

from dgt_lib.core.geometry import GridSpec
from dgt_lib.mapping.methods import METHOD_LABELS

CONTRAST_THRESHOLD = 0.3
"""Opposite-heading pairs count for the directional contrast when |C*(θ) − C*(θ+π)| > it."""


def cost_at(cost: np.ndarray, grid: GridSpec, cells: np.ndarray, n_headings: int
            ) -> np.ndarray:
    """(N, K) the cost of a (K', H, W) costmap at each cell and heading layer θ_k: layer k
    when K' = K, the single layer for every heading when K' = 1."""
    cost = np.asarray(cost)
    if cost.ndim != 3 or cost.shape[0] not in (1, n_headings):
        raise ValueError(f"cost must be (K, H, W) with K = {n_headings} or 1, got {cost.shape}")
    rows, cols = grid.xy_to_cell(cells[:, 0], cells[:, 1])
    rows = np.clip(rows, 0, cost.shape[1] - 1)
    cols = np.clip(cols, 0, cost.shape[2] - 1)
    c = cost[:, rows, cols].T.astype(np.float64)  # (N, K')
    return np.repeat(c, n_headings, axis=1) if cost.shape[0] == 1 else c


def free_cells(occupancy: np.ndarray, grid: GridSpec, cells: np.ndarray) -> np.ndarray:
    """(N,) bool: the cells the occupancy map marks free (0)."""
    rows, cols = grid.xy_to_cell(cells[:, 0], cells[:, 1])
    rows = np.clip(rows, 0, occupancy.shape[0] - 1)
    cols = np.clip(cols, 0, occupancy.shape[1] - 1)
    return occupancy[rows, cols] == 0


def contrast_pairs(true_cost: np.ndarray, valid: np.ndarray,
                   threshold: float = CONTRAST_THRESHOLD) -> tuple[np.ndarray, np.ndarray]:
    """The opposite-heading pairs of (N, K) ``true_cost`` whose two samples are ``valid``
    and differ by more than ``threshold``: (cell index (P,), heading index k (P,)), each
    pair (i, k) with k < K/2 standing for θ_k and θ_{k + K/2}."""
    n, k = true_cost.shape
    if k % 2:
        raise ValueError(f"opposite headings need an even K, got {k}")
    half = k // 2
    a, b = true_cost[:, :half], true_cost[:, half:]
    ok = valid[:, :half] & valid[:, half:]
    with np.errstate(invalid="ignore"):
        ok &= np.abs(a - b) > threshold
    return np.nonzero(ok)


def costmap_accuracy(true_cost: np.ndarray, cost: np.ndarray, valid: np.ndarray,
                     threshold: float = CONTRAST_THRESHOLD) -> dict[str, float | int]:
    """Accuracy of a costmap's (N, K) ``cost`` against (N, K) ``true_cost`` C* on the
    ``valid`` samples (see the module docstring).

    Returns ``n``, ``mae``, ``spearman`` (NaN when either side is constant or n < 3),
    ``pairs`` (the contrast pairs), ``contrast_true`` and ``contrast`` (mean |ΔC| over
    them) and ``sign_agreement`` (fraction of pairs where the method's ΔC has the
    truth's sign; NaN without pairs)."""
    valid = np.asarray(valid, bool) & np.isfinite(true_cost) & np.isfinite(cost)
    t, c = true_cost[valid], cost[valid]
    out: dict[str, float | int] = {"n": int(valid.sum()), "mae": math.nan,
                                   "spearman": math.nan, "pairs": 0, "contrast_true": math.nan,
                                   "contrast": math.nan, "sign_agreement": math.nan}
    if len(t):
        out["mae"] = float(np.mean(np.abs(c - t)))
    if len(t) >= 3 and np.ptp(t) > 0 and np.ptp(c) > 0:
        out["spearman"] = float(stats.spearmanr(c, t).statistic)
    i, k = contrast_pairs(true_cost, valid, threshold)
    if len(i):
        half = true_cost.shape[1] // 2
        d_true = true_cost[i, k] - true_cost[i, k + half]
        d = cost[i, k] - cost[i, k + half]
        out.update(pairs=int(len(i)), contrast_true=float(np.mean(np.abs(d_true))),
                   contrast=float(np.mean(np.abs(d))),
                   sign_agreement=float(np.mean(np.sign(d) == np.sign(d_true))))
    return out


# ----------------------------------------------------------------------------- tables


def _f(x: float | None, digits: int = 2) -> str:
    return "—" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def accuracy_table(rows: Sequence[Mapping]) -> str:
    """Markdown: one row per (world, vehicle, method) of ``rows`` (each a
    :func:`costmap_accuracy` dict plus ``world``, ``vehicle``, ``method``)."""
    lines = ["| world | vehicle | method | n | MAE | Spearman ρ | pairs | contrast: truth | "
             "contrast: method | same sign |", "|" + "---|" * 10]
    for r in rows:
        sign = f"{100 * r['sign_agreement']:.0f} %" if r["pairs"] else "—"
        lines.append(
            f"| {r['world']} | {r['vehicle']} | {METHOD_LABELS.get(r['method'], r['method'])} "
            f"| {r['n']} | {_f(r['mae'], 3)} | {_f(r['spearman'])} | {r['pairs']} | "
            f"{_f(r['contrast_true'])} | {_f(r['contrast'])} | {sign} |")
    return "\n".join(lines) + "\n"


def pooled_by_vehicle(rows: Sequence[Mapping], methods: Sequence[str]
                      ) -> dict[str, dict[str, dict[str, float]]]:
    """{vehicle: {method: {n, mae, spearman}}} over every world of ``rows``: the MAE
    weighted by samples, ρ the samples-weighted mean of the worlds' ρ."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for v in dict.fromkeys(r["vehicle"] for r in rows):
        for m in methods:
            rs = [r for r in rows if r["vehicle"] == v and r["method"] == m and r["n"]]
            if not rs:
                continue
            n = sum(r["n"] for r in rs)
            rho = [(r["spearman"], r["n"]) for r in rs if math.isfinite(r["spearman"])]
            out.setdefault(v, {})[m] = {
                "n": n, "mae": sum(r["mae"] * r["n"] for r in rs) / n,
                "spearman": (sum(a * b for a, b in rho) / sum(b for _, b in rho)) if rho
                else math.nan}
    return out


def multitask_table(rows: Sequence[Mapping]) -> str:
    """Markdown: multi-task (DGT-Map) against single-task per vehicle over its worlds —
    MAE and ρ of each, and which is closer to the ground truth (Claim 4 without the
    closed loop)."""
    pooled = pooled_by_vehicle(rows, ("dgt", "single-task"))
    lines = ["| vehicle | worlds | n | MAE multi-task | MAE single-task | ρ multi-task | "
             "ρ single-task | lower MAE |", "|" + "---|" * 8]
    for v, d in pooled.items():
        if "dgt" not in d or "single-task" not in d:
            continue
        mt, st = d["dgt"], d["single-task"]
        worlds = ", ".join(dict.fromkeys(r["world"] for r in rows if r["vehicle"] == v))
        better = ("multi-task" if mt["mae"] < st["mae"] else
                  "single-task" if st["mae"] < mt["mae"] else "tie")
        lines.append(f"| {v} | {worlds} | {mt['n']} | {_f(mt['mae'], 3)} | "
                     f"{_f(st['mae'], 3)} | {_f(mt['spearman'])} | {_f(st['spearman'])} | "
                     f"{better} |")
    return "\n".join(lines) + "\n"


def accuracy_over_seeds(per_seed: Mapping[int, Sequence[Mapping]]) -> str:
    """Markdown: MAE and ρ of every (world, vehicle, method) in each seed, and their mean
    over the seeds (the ground truth is the same in every seed; the maps are not)."""
    seeds = list(per_seed)
    keys = list(dict.fromkeys((r["world"], r["vehicle"], r["method"])
                              for rows in per_seed.values() for r in rows))
    head = ["world", "vehicle", "method", *[f"seed {s}: MAE / ρ" for s in seeds],
            "mean MAE", "mean ρ"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for w, v, m in keys:
        cells, maes, rhos = [w, v, METHOD_LABELS.get(m, m)], [], []
        for s in seeds:
            r = next((r for r in per_seed[s] if (r["world"], r["vehicle"], r["method"])
                      == (w, v, m)), None)
            if r is None or not r["n"]:
                cells.append("—")
                continue
            cells.append(f"{_f(r['mae'], 3)} / {_f(r['spearman'])}")
            maes.append(r["mae"])
            if math.isfinite(r["spearman"]):
                rhos.append(r["spearman"])
        cells += [_f(float(np.mean(maes)), 3) if maes else "—",
                  _f(float(np.mean(rhos))) if rhos else "—"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
