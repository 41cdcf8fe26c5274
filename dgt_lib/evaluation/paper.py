"""The paper's own numbers, to print beside ours (paper: Tables I and II).

Keyed by this kit's method vocabulary (:data:`dgt_lib.mapping.methods.METHODS`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass


@dataclass(frozen=True)
class PaperResult:
    """One column group of the paper's tables: an environment, its vehicle, n trials and
    the successes k per method."""

    experiment: str
    vehicle: str
    n: int
    k: Mapping[str, int]


# Table I ("Navigation Success Rate on two test maps"): Hill with CarlaCola (n = 20),
# Ridge with MercedesVan (n = 50). Table II ("Navigation Success Rate on Random
# Start-and-Goal Tasks"): Jeep (n = 100) and VolkswagenVan (n = 99).
PAPER_TABLE_I: dict[str, PaperResult] = {
    "hill": PaperResult("hill", "carla_cola", 20, {
        "dgt": 16, "isotropic": 10, "single-task": 5, "slope": 16, "binary": 10}),
    "ridge": PaperResult("ridge", "mercedes_van", 50, {
        "dgt": 47, "isotropic": 45, "single-task": 14, "slope": 26, "binary": 20}),
}
PAPER_TABLE_II: dict[str, PaperResult] = {
    "jeep": PaperResult("random", "jeep", 100, {"dgt": 70, "single-task": 64}),
    "vw_van": PaperResult("random", "vw_van", 99, {"dgt": 54, "single-task": 35}),
}
PAPER: dict[str, dict[str, PaperResult]] = {
    "experiment1": {"carla_cola": PAPER_TABLE_I["hill"]},
    "experiment2": {"mercedes_van": PAPER_TABLE_I["ridge"]},
    "experiment3": {"jeep": PAPER_TABLE_II["jeep"], "vw_van": PAPER_TABLE_II["vw_van"]},
}
"""The paper's results per experiment and vehicle."""
