"""The trials' controllers by name (``ExperimentsConfig.controller``, docs/controller.md).

- ``"paper"``: MPPI as the paper runs it (every :class:`MPPIConfig` default; no terrain term).
- ``"robust"``: the same MPPI that does not crawl and does not corner past the roll limit:
  its model stands still below a breakaway speed, and the sent speeds are slowed below half
  the vehicle's rollover acceleration.
- ``"terrain"``: ``"robust"`` plus the terrain critic reading the trial method's own
  costmap (Binary's is zero: no terrain term).
"""

from __future__ import annotations

CONTROLLERS: tuple[str, ...] = ("paper", "robust", "terrain")
"""Valid ``ExperimentsConfig.controller`` values; the first is the default."""

ROBUST: dict[str, object] = {
    "breakaway_speed_mps": 0.5,  # a command below this does not move a truck on a grade
    "roll_limit_fraction": 0.5,  # corners at most half the static rollover acceleration
}  # first_step_weight stays 0: it carries speed into corners (docs/controller.md)
TERRAIN: dict[str, object] = {**ROBUST, "terrain_weight": 0.05}  # docs/controller.md


def controller_settings(name: str) -> dict[str, object]:
    """The :class:`~dgt_lib.navigation.control.mppi_config.MPPIConfig` fields a named
    controller changes (none for ``"paper"``)."""
    if name not in CONTROLLERS:
        raise ValueError(f"unknown controller {name!r}; valid: {', '.join(CONTROLLERS)}")
    return {"paper": {}, "robust": dict(ROBUST), "terrain": dict(TERRAIN)}[name]


def reads_costmap(name: str) -> bool:
    """Whether the named controller's trials hand MPPI the method's costmap."""
    return name == "terrain"
