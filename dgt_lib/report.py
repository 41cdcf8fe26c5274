"""The results report of ``dgt reproduce``: tables and figures of Experiments 1–3.

Writes ``data/<profile>/results/README.md`` — each experiment's table (ours beside the
paper's, with Wilson 95 % intervals), the routes each method planned, the failure
reasons — and beside it the figures: planned paths per method (the paper's path
figure) and success rates.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg", force=False)
import matplotlib.pyplot as plt  # noqa: E402

from . import viz  # noqa: E402
from .artifacts import profile_dir  # noqa: E402
from .config import Profile  # noqa: E402
from .experiments import PAPER, ExperimentResult  # noqa: E402
from .inference import ensure_world_costmaps  # noqa: E402
from .worlds import get_world  # noqa: E402

TITLES = {"experiment1": "Experiment 1 — hill, carla_cola (paper Table I, left)",
          "experiment2": "Experiment 2 — ridge, mercedes_van (paper Table I, right)",
          "experiment3": "Experiment 3 — random queries, jeep and vw_van (paper Table II)"}


def _figures(result: ExperimentResult, prof: Profile, out: Path) -> list[Path]:
    paths = []
    fig = viz.plot_success_rates(result, PAPER.get(result.name))
    paths.append(out / f"{result.name}_success.png")
    fig.savefig(paths[-1], dpi=90)
    plt.close(fig)
    labels = sorted({r.task.query.label for r in result.results})
    if result.world in ("hill", "ridge"):
        world = get_world(result.world, prof)
        vehicles = tuple(sorted({r.task.vehicle for r in result.results}))
        maps = ensure_world_costmaps(result.world, vehicles, prof, progress=False)
        fig, axes = plt.subplots(1, len(labels), figsize=(7 * len(labels), 6.5), squeeze=False)
        for ax, label in zip(axes[0], labels, strict=True):
            viz.plot_planned_paths(ax, world, maps, result, label)
        fig.tight_layout()
        paths.append(out / f"{result.name}_paths.png")
        fig.savefig(paths[-1], dpi=90)
        plt.close(fig)
    return paths


def write_results(results: list[ExperimentResult], prof: Profile) -> Path:
    """Write ``results/README.md`` and its figures; returns the markdown's path."""
    out = profile_dir(prof.name) / "results"
    out.mkdir(parents=True, exist_ok=True)
    parts = [f"# Results — profile `{prof.name}`", "",
             "Every number below was measured by `dgt reproduce` on this machine; the paper's "
             "numbers stand beside ours. Intervals are Wilson 95 %.", ""]
    for result in results:
        parts += [f"## {TITLES.get(result.name, result.name)}", "",
                  result.markdown(PAPER.get(result.name)), ""]
        parts += [f"![{p.stem}]({p.name})" for p in _figures(result, prof, out)] + [""]
    path = out / "README.md"
    path.write_text("\n".join(parts))
    return path
