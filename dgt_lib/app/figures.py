"""The README's figures, drawn from one profile's cached run by the library's own plots.

    python -m dgt_lib.app.figures --profile demo            # → docs/figures/*.png (make figures)
    python -m dgt_lib.app.figures --profile smoke --out /tmp/figures --seed 0

Every figure reads the run's artifacts through the ``ensure_*`` functions (a missing one
is built, as ``dgt reproduce`` would) and is drawn by :mod:`dgt_lib.viz`, the functions the
notebooks and the results report use. The hero figure shows the paper's two planning
claims: DGT-Map plans carla_cola up the hill by Route A and down by Route B (Experiment 1),
and on the ridge the jeep crosses the sharp ridge while the mercedes_van goes round by the
smoothed section (Experiment 2); without ``--seed`` they are drawn from the run's first
seed whose record says all four held (:data:`~dgt_lib.records.tables.ROUTE_CLAIMS`), so
that the picture shows what the run concluded, and the caption says how often. A PNG over
:data:`MAX_BYTES` is saved with a 256-colour palette, which keeps it small enough for the
repository. ``README.md`` beside the figures records the profile, seed and commit they
come from.
"""

from __future__ import annotations

import argparse
import io
import json
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

import matplotlib

matplotlib.use("Agg", force=False)
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.cm import ScalarMappable  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402
from PIL import Image  # noqa: E402

from dgt_lib import viz  # noqa: E402
from dgt_lib.core.config import Profile, get_profile  # noqa: E402
from dgt_lib.core.vehicles import get_vehicle  # noqa: E402
from dgt_lib.evaluation.paper import PAPER  # noqa: E402
from dgt_lib.evaluation.queries import classify_route, hill_queries, ridge_queries  # noqa: E402
from dgt_lib.mapping.methods import METHOD_LABELS  # noqa: E402
from dgt_lib.navigation.planner import HybridAStar, PlanResult  # noqa: E402
from dgt_lib.records import tables  # noqa: E402
from dgt_lib.records.provenance import processor_label, provenance  # noqa: E402
from dgt_lib.records.record import seed_summaries  # noqa: E402
from dgt_lib.stages.costmaps import ensure_world_costmaps, world_bev  # noqa: E402
from dgt_lib.stages.experiments import ensure_experiment  # noqa: E402
from dgt_lib.viz.common import COST_CMAP, COST_LABEL  # noqa: E402
from dgt_lib.world.terrain import get_world  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "figures"
FACTS = "figures.json"
"""Beside the figures: the run they were drawn from (with a digest of its seed record's
results, which ``make docs`` finds among the published runs' records) and what the hero
figure shows (the route of each plan), for the README's caption."""
MAX_BYTES = 300_000
"""The largest PNG the repository takes [bytes]."""
DPI = 80


def save_png(fig, path: Path, dpi: int = DPI, max_bytes: int = MAX_BYTES) -> Path:
    """Save ``fig`` as a PNG and close it. A PNG over ``max_bytes`` is saved with an
    adaptive 256-colour palette instead (3.5–6× smaller for these plots; smooth colour
    ramps then show faint bands)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    if buf.tell() <= max_bytes:
        Path(path).write_bytes(buf.getvalue())
        return path
    buf.seek(0)
    image = Image.open(buf).convert("RGB").quantize(256, method=Image.Quantize.MAXCOVERAGE)
    image.save(path, format="PNG", optimize=True)
    return path


def _plan(maps, vehicle: str, query, prof: Profile) -> PlanResult:
    """DGT-Map's plan of one query for one vehicle, by the experiments' planner settings."""
    planner = HybridAStar.for_vehicle(maps.costmap("dgt", vehicle), maps.occupancy, maps.grid,
                                      get_vehicle(vehicle), prof.planner)
    return planner.plan(query.start, query.goal)


@lru_cache(maxsize=2)
def hero_plans(prof: Profile) -> dict[str, PlanResult]:
    """The hero figure's plans, by DGT-Map: Experiment 1's first ascent and descent for
    carla_cola, and Experiment 2's first northbound query for the jeep and for the
    mercedes_van (the queries the experiments draw first, not picked)."""
    hill, ridge = get_world("hill", prof), get_world("ridge", prof)
    hill_maps = ensure_world_costmaps("hill", ("carla_cola",), prof, progress=False)
    ridge_maps = ensure_world_costmaps("ridge", ("mercedes_van", "jeep"), prof, progress=False)
    ascent, descent = hill_queries(hill, 2, prof.experiments, prof.seed)
    north = ridge_queries(ridge, 1, prof.experiments, prof.seed)[0]
    return {"ascent": _plan(hill_maps, "carla_cola", ascent, prof),
            "descent": _plan(hill_maps, "carla_cola", descent, prof),
            "jeep": _plan(ridge_maps, "jeep", north, prof),
            "mercedes_van": _plan(ridge_maps, "mercedes_van", north, prof)}


def hero_routes(prof: Profile) -> dict[str, str]:
    """Which way each of :func:`hero_plans` went (:func:`classify_route`; "no path")."""
    worlds = {"ascent": "hill", "descent": "hill", "jeep": "ridge", "mercedes_van": "ridge"}
    return {name: classify_route(get_world(worlds[name], prof), plan.path) if plan.success
            else "no path" for name, plan in hero_plans(prof).items()}


def hero(prof: Profile):
    """Experiment 1's first ascent and descent on carla_cola's DGT-Map layer for heading
    north (uphill on Route B), and Experiment 2's first northbound query planned for the
    jeep and for the mercedes_van, each on its own DGT-Map layer for heading north."""
    k_north = prof.costmap.n_headings // 4
    hill, ridge = get_world("hill", prof), get_world("ridge", prof)
    hill_maps = ensure_world_costmaps("hill", ("carla_cola",), prof, progress=False)
    ridge_maps = ensure_world_costmaps("ridge", ("mercedes_van", "jeep"), prof, progress=False)
    plans, routes = hero_plans(prof), hero_routes(prof)  # each plan labelled with its route
    named = {k: f"{k}: Route {r}" if k in ("ascent", "descent") else f"{k}: {r} crossing"
             for k, r in routes.items() if r != "no path"}
    fig, axes = plt.subplots(1, 3, figsize=(18, 6.2), gridspec_kw={"width_ratios": [1.4, 1, 1]},
                             layout="constrained")
    viz.plot_plans(hill, {named.get(k, k): plans[k] for k in ("ascent", "descent")}, axes[0],
                   background=hill_maps.costmap("dgt", "carla_cola")[k_north],
                   title="Hill, carla_cola: DGT-Map cost heading north")
    for ax, vehicle in zip(axes[1:], ("jeep", "mercedes_van"), strict=True):
        viz.plot_plans(ridge, {named.get(vehicle, vehicle): plans[vehicle]}, ax,
                       background=ridge_maps.costmap("dgt", vehicle)[k_north],
                       title=f"Ridge, {vehicle}: DGT-Map cost heading north")
    fig.colorbar(ScalarMappable(Normalize(0, 1), cmap=COST_CMAP), ax=list(axes), shrink=0.8,
                 label=COST_LABEL)
    fig.suptitle("DGT-Map: one network, one head per vehicle, one cost layer per heading "
                 "(here north); the plans on it, by Hybrid A*")
    return fig


def experiment1_paths(prof: Profile):
    """Every method's planned and driven path of Experiment 1's first ascent and descent
    (the paper's path figure), from the recorded trials."""
    result = ensure_experiment("experiment1", prof, progress=False)
    hill = get_world("hill", prof)
    maps = ensure_world_costmaps("hill", ("carla_cola",), prof, progress=False)
    fig, axes = plt.subplots(1, 2, figsize=(14, 6.5))
    for ax, label in zip(axes, ("ascent", "descent"), strict=True):
        viz.plot_planned_paths(ax, hill, maps, result, label)
    fig.tight_layout()
    return fig


def costmap_headings(prof: Profile):
    """carla_cola's K DGT-Map layers on the hill: the same ground costs differently by
    heading."""
    maps = ensure_world_costmaps("hill", ("carla_cola",), prof, progress=False)
    return viz.plot_heading_layers(maps.costmap("dgt", "carla_cola"), maps.grid,
                                   world=get_world("hill", prof),
                                   title="DGT-Map, carla_cola on the hill: one layer per heading")


def experiment2_success(prof: Profile):
    """Experiment 2's success rate per method (Wilson 95 % intervals) beside the paper's."""
    result = ensure_experiment("experiment2", prof, progress=False)
    return viz.plot_success_rates(result, PAPER["experiment2"])


def bev_hill(prof: Profile):
    """The hill's global BEV map: colour, mean height H̄, roughness σ_H, gradient ‖∇H̄‖."""
    bev, _ = world_bev("hill", prof, progress=False)
    return viz.plot_bev(bev, title="hill")


def experiment1_failures(prof: Profile):
    """Where Experiment 1's failed trials ended (marker by reason, colour by method)."""
    result = ensure_experiment("experiment1", prof, progress=False)
    return viz.plot_failure_map(get_world("hill", prof), result)


FIGURES: dict[str, Callable[[Profile], object]] = {
    "hero": hero, "experiment1_paths": experiment1_paths, "costmap_headings": costmap_headings,
    "experiment2_success": experiment2_success, "bev_hill": bev_hill,
    "experiment1_failures": experiment1_failures}
"""Each figure's file stem and the function that draws it from a profile's run."""


SCRIPTS_SECTION = "Drawn by scripts of their own:"
"""The heading in the figures' ``README.md`` under which the figures drawn by studies and
examples are listed by hand, each with its command: kept when the README is rewritten."""


def make_figures(profile: str | Profile = "demo", out: Path = OUT,
                 names: tuple[str, ...] = tuple(FIGURES)) -> list[Path]:
    """Draw the named figures of ``profile``'s run (its ``seed``) into ``out``; write
    ``out/README.md`` saying where they come from. Returns the PNG paths."""
    prof = get_profile(profile) if isinstance(profile, str) else profile
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [save_png(FIGURES[name](prof), out / f"{name}.png") for name in names]
    made = {**provenance(), "profile": prof.name, "seed": prof.seed, "results": next(  # its run
        (tables.results_digest(s) for s in seed_summaries(prof) if s["seed"] == prof.seed), None)}
    if "hero" in names:
        made["hero_routes"] = hero_routes(prof)
    (out / FACTS).write_text(json.dumps(made, indent=1) + "\n")
    lines = ["# Figures", "",
             f"Drawn by `python -m dgt_lib.app.figures --profile {prof.name} --seed {prof.seed}` "
             f"from the `{prof.name}` profile's run seed {prof.seed}, with the code at commit "
             f"`{made['commit'][:7]}` on {processor_label(made['processor'])} (`make figures` "
             f"draws the `demo` run's first seed in which DGT-Map's four route claims held; "
             f"what they show: `figures.json`). Methods: "
             f"{', '.join(METHOD_LABELS.values())}.", ""]
    lines += [f"- [`{p.name}`]({p.name}): {' '.join(FIGURES[p.stem].__doc__.split())}"
              for p in paths]
    old = (out / "README.md").read_text() if (out / "README.md").exists() else ""
    scripts = old[old.index(SCRIPTS_SECTION):] if SCRIPTS_SECTION in old else ""
    (out / "README.md").write_text("\n".join(lines) + "\n" + (scripts and "\n" + scripts))
    return paths


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m dgt_lib.app.figures", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="demo", help="the run to draw (default demo)")
    parser.add_argument("--seed", type=int, help="its run seed (default: the first whose "
                        "record says DGT-Map's route claims held; 0 without one)")
    parser.add_argument("--out", type=Path, default=OUT, help="folder (default docs/figures)")
    parser.add_argument("--only", nargs="+", choices=list(FIGURES), default=list(FIGURES))
    args = parser.parse_args(argv)
    prof = get_profile(args.profile)
    if args.seed is None:  # the first seed whose record says the route claims held, or 0
        args.seed = next(iter(tables.seeds_holding(seed_summaries(prof))), 0)
    prof = prof.with_(seed=args.seed)
    for path in make_figures(prof, args.out, tuple(args.only)):
        print(f"{path}  {path.stat().st_size / 1000:.0f} kB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
