"""The layout of a rerun recording (:mod:`dgt_lib.viz.recording`): its entity paths, and the
blueprint built from what a recording logged, so every entity is in some view."""

from __future__ import annotations

from dataclasses import dataclass, field

import rerun.blueprint as rrb

from dgt_lib.mapping.methods import METHOD_LABELS

WORLD = "world"
TERRAIN = "world/terrain"
FRAMES = "world/frames"
PATHS = "world/paths"
VEHICLES = "world/vehicle"
COSTMAPS = "world/costmap"
BEV = "maps/bev"
OCCUPANCY = "maps/occupancy"
PLOTS = "plots"
NOTES = "notes"

BEV_NAMES = ("rgb", "height", "std", "gradient")
BEV_TITLES = {"height": "H̄ [m]", "std": "σ_H [m]", "gradient": "‖∇H̄‖"}


@dataclass(frozen=True)
class ViewSpec:
    """One view of a blueprint: its kind, origin and contents (rerun query expressions)."""

    kind: type
    origin: str
    name: str
    contents: tuple[str, ...] = ("$origin/**",)
    hidden: tuple[str, ...] = ()  # entities drawn only when switched on in the blueprint panel

    def view(self) -> rrb.View:
        overrides = {path: rrb.EntityBehavior(visible=False) for path in self.hidden}
        return self.kind(origin=self.origin, name=self.name, contents=list(self.contents),
                         **({"overrides": overrides} if overrides else {}))

    def shows(self, path: str) -> bool:
        """Whether ``path`` is in this view (its contents' ``+``/``-`` rules, later wins)."""
        shown = False
        for expr in self.contents:
            sign, _, rule = expr.partition(" ") if expr[:2] in ("+ ", "- ") else ("+", "", expr)
            rule = rule.replace("$origin", self.origin).strip("/")
            if rule.endswith("/**"):
                base = rule[:-3]
                match = path == base or path.startswith(base + "/")
            else:
                match = path == rule
            if match:
                shown = sign == "+"
        return shown


@dataclass
class Layout:
    """What a recording logged, and the blueprint built from it."""

    entities: set[str] = field(default_factory=set)
    costmaps: dict[tuple[str, str], int] = field(default_factory=dict)  # (vehicle, method) → K
    titles: dict[str, str] = field(default_factory=dict)  # entity → its view's name
    runs: int = 0  # trajectories logged

    def views(self) -> tuple[list[ViewSpec], list[ViewSpec]]:
        """(left column, right tabs) of the blueprint."""
        logged = self.entities
        left = [ViewSpec(rrb.Spatial3DView, WORLD, "world",
                         ("$origin/**", f"- {COSTMAPS}/**"))]
        if any(p.startswith(PLOTS + "/") for p in logged):
            left.append(ViewSpec(rrb.TimeSeriesView, PLOTS, "plots"))
        right = []
        for (vehicle, method), k in sorted(self.costmaps.items()):
            base = f"{COSTMAPS}/{vehicle}/{method}"
            right.append(ViewSpec(
                rrb.Spatial3DView, WORLD,
                f"costmap {METHOD_LABELS.get(method, method)} · {vehicle}",
                (f"+ {TERRAIN}", f"+ {base}/**"),
                tuple(f"{base}/heading_{i}" for i in range(1, k))))
        right += [ViewSpec(rrb.Spatial2DView, p, self.titles.get(p, p))
                  for p in (f"{BEV}/{ch}" for ch in (*BEV_NAMES, "observed")) if p in logged]
        if OCCUPANCY in logged:
            right.append(ViewSpec(rrb.Spatial2DView, OCCUPANCY, "occupancy"))
        right += [ViewSpec(rrb.TextDocumentView, p, p.split("/", 1)[1])
                  for p in sorted(logged) if p.startswith(NOTES + "/")]
        return left, right

    def blueprint(self) -> rrb.Blueprint:
        """3D world (and plots) on the left; costmaps, BEV, occupancy and notes tabbed on
        the right; every panel expanded, the time panel on ``elapsed`` when runs were
        logged."""
        left, right = self.views()
        column = (rrb.Vertical(*[v.view() for v in left], row_shares=[3, 1])
                  if len(left) > 1 else left[0].view())
        root = rrb.Horizontal(column, rrb.Tabs(*[v.view() for v in right]),
                              column_shares=[3, 2]) if right else column
        return rrb.Blueprint(
            root, rrb.BlueprintPanel(state="expanded"), rrb.SelectionPanel(state="expanded"),
            rrb.TimePanel(state="expanded", timeline="elapsed" if self.runs else None),
            collapse_panels=False)
