"""Success rates with Wilson intervals, outcome counts and markdown tables
(paper: Tables I and II; we add 95 % intervals the paper does not give)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from statistics import NormalDist

import numpy as np

from dgt_lib.mapping.methods import METHOD_LABELS
from dgt_lib.navigation.outcome import REASONS, TrialOutcome


def n_seeds(n: int) -> str:
    """``1 seed``, ``8 seeds``: how many seeds a pooled figure rests on."""
    return f"{n} seed{'s' if n != 1 else ''}"


def wilson_interval(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion k/n::

        p̂ = k/n,  z = Φ⁻¹(1 − α/2),
        (p̂ + z²/2n ± z·√(p̂(1−p̂)/n + z²/4n²)) / (1 + z²/n)

    Returns (low, high) in [0, 1]. E.g. k=16, n=20 → (0.584, 0.919).
    """
    if not (isinstance(n, (int, np.integer)) and isinstance(k, (int, np.integer))):
        raise TypeError(f"k and n must be integers, got {k!r}, {n!r}")
    if n < 1 or not 0 <= k <= n:
        raise ValueError(f"need n ≥ 1 and 0 ≤ k ≤ n, got k={k}, n={n}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    z = NormalDist().inv_cdf(1.0 - (1.0 - confidence) / 2.0)
    p = k / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    low = 0.0 if k == 0 else max(0.0, centre - half)  # exact bounds, not rounding noise
    high = 1.0 if k == n else min(1.0, centre + half)
    return low, high


def success_rows(
    counts: Mapping[str, tuple[int, int]],
    confidence: float = 0.95,
    paper: Mapping[str, int] | None = None,
    paper_n: int | None = None,
) -> list[dict]:
    """One row per method from ``counts`` {method: (k, n)}, in the mapping's order:
    ``method, k, n, sr_pct, ci_low_pct, ci_high_pct`` (percent), plus
    ``paper_k, paper_sr_pct`` when ``paper`` {method: k} and ``paper_n`` are given
    (None for a method the paper lacks)."""
    rows = []
    for method, (k, n) in counts.items():
        lo, hi = wilson_interval(k, n, confidence)
        row = {
            "method": method,
            "k": int(k),
            "n": int(n),
            "sr_pct": 100.0 * k / n,
            "ci_low_pct": 100.0 * lo,
            "ci_high_pct": 100.0 * hi,
        }
        if paper is not None:
            if paper_n is None:
                raise ValueError("paper_n is needed with paper counts")
            pk = paper.get(method)
            row["paper_k"] = pk
            row["paper_sr_pct"] = None if pk is None else 100.0 * pk / paper_n
        rows.append(row)
    return rows


def reason_counts(outcomes: Iterable[TrialOutcome]) -> dict[str, int]:
    """How many trials ended for each reason, in :data:`REASONS` order (zeros kept)."""
    counts = dict.fromkeys(REASONS, 0)
    for o in outcomes:
        counts[o.reason] += 1
    return counts


def markdown_table(rows: Sequence[Mapping], title: str | None = None) -> str:
    """A markdown table of :func:`success_rows` output (with the paper's columns when
    the rows carry them). Methods are shown by :data:`METHOD_LABELS` (unknown keys as
    they are)."""
    with_paper = any("paper_k" in r for r in rows)
    head = ["method", "k / n", "SR %", "95 % CI %"]
    if with_paper:
        head += ["paper k", "paper SR %"]
    lines = [] if title is None else [f"**{title}**", ""]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [
            METHOD_LABELS.get(r["method"], str(r["method"])),
            f"{r['k']} / {r['n']}",
            f"{r['sr_pct']:.1f}",
            f"{r['ci_low_pct']:.1f}–{r['ci_high_pct']:.1f}",
        ]
        if with_paper:
            pk = r.get("paper_k")
            cells += ["—", "—"] if pk is None else [str(pk), f"{r['paper_sr_pct']:.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
