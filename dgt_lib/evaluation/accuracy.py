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
same cost. Multi-task and single-task maps are compared per vehicle on the very same
samples, with a paired test (:func:`multitask_comparisons`): Claim 4 without the closed
loop's noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from dgt_lib.core.geometry import GridSpec
from dgt_lib.evaluation.statistics import n_seeds
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


PairSelection = Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]
"""(C* (N, K), valid (N, K), threshold) → (cell indices, k) of the contrast pairs."""


def costmap_accuracy(true_cost: np.ndarray, cost: np.ndarray, valid: np.ndarray,
                     threshold: float = CONTRAST_THRESHOLD, *,
                     select_pairs: PairSelection = contrast_pairs) -> dict[str, float | int]:
    """Accuracy of a costmap's (N, K) ``cost`` against (N, K) ``true_cost`` C* on the
    ``valid`` samples (see the module docstring).

    Returns ``n``, ``mae``, ``spearman`` (NaN when either side is constant or n < 3),
    ``pairs`` (the contrast pairs), ``contrast_true`` and ``contrast`` (mean |ΔC| over
    them) and ``sign_agreement`` (fraction of pairs where the method's ΔC has the
    truth's sign; NaN without pairs). ``select_pairs(true_cost, valid, threshold)`` picks
    the pairs (:func:`contrast_pairs`; notebook 09's exercise plugs the learner's in)."""
    valid = np.asarray(valid, bool) & np.isfinite(true_cost) & np.isfinite(cost)
    t, c = true_cost[valid], cost[valid]
    out: dict[str, float | int] = {"n": int(valid.sum()), "mae": math.nan,
                                   "spearman": math.nan, "pairs": 0, "contrast_true": math.nan,
                                   "contrast": math.nan, "sign_agreement": math.nan}
    if len(t):
        out["mae"] = float(np.mean(np.abs(c - t)))
    if len(t) >= 3 and np.ptp(t) > 0 and np.ptp(c) > 0:
        from scipy import stats  # ~0.3 s to import: kept off `dgt plan`'s path (via viz)

        out["spearman"] = float(stats.spearmanr(c, t).statistic)
    i, k = select_pairs(true_cost, valid, threshold)
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


def paired_comparison(cost_a: np.ndarray, cost_b: np.ndarray, true_cost: np.ndarray
                      ) -> dict[str, float | int]:
    """Two maps' costs (n,) at the same samples against their C* (n,): ``n``, ``mae_a``,
    ``mae_b``, ``spearman_a``, ``spearman_b`` and ``p``, the two-sided Wilcoxon
    signed-rank test of |C_a − C*| against |C_b − C*| sample by sample (1 when the two
    never differ; NaN without samples). Paired, because both maps are scored on the very
    same drives."""
    a, b, t = (np.asarray(x, np.float64) for x in (cost_a, cost_b, true_cost))
    out: dict[str, float | int] = {"n": int(len(t)), "mae_a": math.nan, "mae_b": math.nan,
                                   "spearman_a": math.nan, "spearman_b": math.nan,
                                   "p": math.nan}
    if not len(t):
        return out
    from scipy import stats  # imported here, as in costmap_accuracy

    ea, eb = np.abs(a - t), np.abs(b - t)
    out.update(mae_a=float(ea.mean()), mae_b=float(eb.mean()))
    for key, c in (("spearman_a", a), ("spearman_b", b)):
        if len(t) >= 3 and np.ptp(c) > 0 and np.ptp(t) > 0:
            out[key] = float(stats.spearmanr(c, t).statistic)
    out["p"] = 1.0 if np.all(ea == eb) else float(stats.wilcoxon(ea, eb).pvalue)
    return out


SIGNIFICANCE = 0.05
"""A comparison names a winner when its paired test's p is below this …"""
MIN_MAE_DIFFERENCE = 0.005
"""… and the MAEs differ by at least this much: two nearly constant maps (collapsed heads)
differ on every sample by the same hair, which a paired test finds significant."""


def multitask_comparisons(samples: Mapping[tuple[str, str, str], tuple[np.ndarray, np.ndarray]]
                          ) -> list[dict]:
    """Multi-task (``dgt``) against single-task per vehicle, over every world it was
    scored on. ``samples``: {(world, vehicle, method): (cost (n,), C* (n,))} on the scored
    samples. Returns per vehicle ``vehicle``, ``worlds``, the :func:`paired_comparison`
    (``a`` = multi-task, ``b`` = single-task) and ``closer``: "multi-task" or
    "single-task" when that one's MAE is lower by at least :data:`MIN_MAE_DIFFERENCE`
    with p < :data:`SIGNIFICANCE`, else "neither"."""
    out = []
    for v in dict.fromkeys(key[1] for key in samples):
        worlds = [w for (w, vv, m) in samples if vv == v and m == "dgt"
                  and (w, v, "single-task") in samples]
        if not worlds:
            continue
        mt = np.concatenate([samples[(w, v, "dgt")][0] for w in worlds])
        st = np.concatenate([samples[(w, v, "single-task")][0] for w in worlds])
        truth = np.concatenate([samples[(w, v, "dgt")][1] for w in worlds])
        c = paired_comparison(mt, st, truth)
        closer = "neither"
        if c["p"] < SIGNIFICANCE and abs(c["mae_a"] - c["mae_b"]) >= MIN_MAE_DIFFERENCE:
            closer = "multi-task" if c["mae_a"] < c["mae_b"] else "single-task"
        out.append({"vehicle": v, "worlds": worlds, **c, "closer": closer})
    return out


def _p(p: float) -> str:
    return "—" if not math.isfinite(p) else "< 0.001" if p < 0.001 else f"{p:.3f}"


def multitask_table(comparisons: Sequence[Mapping]) -> str:
    """Markdown: multi-task against single-task per vehicle (:func:`multitask_comparisons`)
    — MAE and ρ of each on the same samples, the paired test's p, and which is closer to
    the ground truth (Claim 4 without the closed loop)."""
    lines = ["| vehicle | worlds | n | MAE multi-task | MAE single-task | ρ multi-task | "
             "ρ single-task | p (paired) | closer |", "|" + "---|" * 9]
    for c in comparisons:
        lines.append(f"| {c['vehicle']} | {', '.join(c['worlds'])} | {c['n']} | "
                     f"{_f(c['mae_a'], 3)} | {_f(c['mae_b'], 3)} | {_f(c['spearman_a'])} | "
                     f"{_f(c['spearman_b'])} | {_p(c['p'])} | {c['closer']} |")
    return "\n".join(lines) + "\n"


def multitask_over_seeds(per_seed: Mapping[int, Sequence[Mapping]]) -> str:
    """Markdown: the multi-task against single-task comparison of each vehicle in every
    seed (MAE multi-task / single-task, and which is closer), and in how many seeds the
    multi-task map is significantly closer."""
    seeds = list(per_seed)
    vehicles = list(dict.fromkeys(c["vehicle"] for cs in per_seed.values() for c in cs))
    head = ["vehicle", *[f"seed {s}: MAE multi / single (closer)" for s in seeds],
            "multi-task closer in"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for v in vehicles:
        cells, wins, n = [v], 0, 0
        for s in seeds:
            c = next((c for c in per_seed[s] if c["vehicle"] == v), None)
            if c is None:
                cells.append("—")
                continue
            n += 1
            wins += c["closer"] == "multi-task"
            cells.append(f"{_f(c['mae_a'], 3)} / {_f(c['mae_b'], 3)} ({c['closer']})")
        cells.append(f"{wins} of {n_seeds(n)}")
        lines.append("| " + " | ".join(cells) + " |")
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
