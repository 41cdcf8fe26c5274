"""Colours and helpers shared by several notebooks' figures.

- :data:`VEHICLE_COLORS`: one colour per vehicle (notebooks 02 and 03);
- :data:`METHOD_COLORS`: one colour per compared method (notebooks 03 and 06–08, the
  results report);
- :data:`COST_CMAP` and :data:`COST_LABEL`: the costmaps' colour scale and its label
  (notebooks 04 and 09, the results report);
- :data:`ROUTE_COLORS` and the routes, trees and landmarks drawn over a world figure
  (notebooks 01, 04 and 05);
- unobserved BEV cells masked out of a map layer (notebook 01);
- :func:`source_markdown`: an implementation shown next to its paper equation
  (notebooks 01, 02, 03 and 05).
"""

from __future__ import annotations

import numpy as np

from dgt_lib.core.config import VEHICLES
from dgt_lib.world.worlds import World

ROUTE_COLORS = ("tab:blue", "tab:orange", "tab:purple", "tab:cyan", "tab:pink", "tab:olive")

VEHICLE_COLORS: dict[str, str] = dict(zip(VEHICLES, ("tab:green", "tab:blue", "tab:purple",
                                                     "tab:red"), strict=True))
"""One colour per vehicle, used by every per-vehicle figure."""

METHOD_COLORS = {"dgt": "tab:blue", "isotropic": "tab:cyan", "single-task": "tab:purple",
                 "slope": "tab:red", "binary": "tab:gray"}
"""Line colours of the compared methods (the paper's figure uses blue for DGT-Map, red for
slope-based)."""


COST_CMAP = "magma"
"""Colour scale of every costmap figure: 0 = free (black) … 1 = impassable (white)."""

COST_LABEL = "cost C = 1 − L̂"
"""Colourbar label of every costmap figure."""


def _overlay(ax, world: World, trees: bool = True, labels: bool = True,
             label_color: str = "black") -> None:
    for i, (name, line) in enumerate(world.routes.items()):
        ax.plot(line[:, 0], line[:, 1], "--", lw=1.5, color=ROUTE_COLORS[i % len(ROUTE_COLORS)],
                label=f"route {name}")
    if trees and len(world.trees):
        ax.scatter(world.trees[:, 0], world.trees[:, 1], s=8, c="darkgreen", marker="^",
                   label="trees")
    for name, (x, y) in world.landmarks.items():
        ax.plot(x, y, "o", ms=5, mfc="white", mec="black")
        if labels:
            ax.annotate(name, (x, y), xytext=(3, 3), textcoords="offset points", fontsize=7,
                        color=label_color)
    ax.set_xlim(world.extent[:2])
    ax.set_ylim(world.extent[2:])
    ax.set_aspect("equal")


def _masked(layer: np.ndarray, observed: np.ndarray) -> np.ma.MaskedArray:
    return np.ma.masked_array(layer, mask=~observed)


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
