"""The trials' controllers by name (``ExperimentsConfig.controller``, docs/controller.md).

- ``"paper"``: MPPI as the paper runs it (every :class:`MPPIConfig` default; no terrain term).
- ``"robust"``: the same MPPI that does not crawl on a grade, does not weave into corners
  and does not corner past the roll limit: its model stands still below a breakaway speed,
  its sampled yaw rates vary half as much, the sent speeds are slowed below half the
  vehicle's rollover acceleration, and its model step is the executed control period. With
  half the yaw-rate noise alone, too few samples turn hard enough from a standstill on a plan
  that turns at full lock at once, and it can crawl (docs/controller.md, seed 3); so a tenth
  of its samples are drawn around pure pursuit's rollout along the plan (biased sampling).
- ``"terrain"``: ``"robust"`` plus the terrain critic reading the trial method's own
  costmap (Binary's is zero: no terrain term).
"""

from __future__ import annotations

CONTROLLERS: tuple[str, ...] = ("paper", "robust", "terrain")
"""Valid ``ExperimentsConfig.controller`` values; the first is the default."""

EXECUTED_PERIOD_S = 0.048
"""The control period the trials execute [s]: ``drive``'s 50 ms rounded to whole 8 ms physics
steps (6 × 8 ms); ``"robust"`` models that, the paper's MPPI a 50 ms step."""

ROBUST: dict[str, object] = {
    "breakaway_speed_mps": 0.5,  # a command below this does not move a truck on a grade
    "roll_limit_fraction": 0.5,  # corners at most half the static rollover acceleration
    "model_dt": EXECUTED_PERIOD_S,  # each call's warm-start shift = the time that passed
    "w_rate_std": 0.75,  # half the yaw-rate noise: no weaving into the corners
    # a tenth of the samples around pure pursuit: no crawl at starts that need full lock at
    # once (control/ancillary.py)
    "ancillary_fraction": 0.1,
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
