"""The trials' controller settings: :class:`MPPIConfig`, the Profile's ``mppi`` section
(Nav2's MPPI defaults scaled to the paper's 5 m/s), and the named presets
``experiments.controller`` selects (docs/controller.md):

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

``dgt reproduce --set experiments.controller=robust --set mppi.w_rate_std=1.0`` runs the
robust preset with one of its settings changed: the preset is applied first, then every
``mppi.*`` setting given (:meth:`~dgt_lib.core.config.Profile.with_overrides`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

from dgt_lib.core.constraints import (
    FROM_THE_VEHICLE,
    FROM_THE_VEHICLE_TEXT,
    InvalidSettingError,
    check_section,
)
from dgt_lib.core.overrides import format_setting


@dataclass(frozen=True)
class MPPIConfig:
    """MPPI settings. Sampling sizes and λ are Nav2's defaults; speeds are scaled to
    the paper's 5 m/s commanded speed (Nav2's defaults are for a 0.5 m/s robot).

    Critic weights multiply dimensionless costs of order 1 per trajectory (see
    :meth:`MPPIController.compute`), so ``temperature`` compares directly with them.
    """

    batch_size: int = 1000  # sampled sequences (Nav2 batch_size)
    time_steps: int = 56  # horizon steps (Nav2 time_steps)
    model_dt: float = 0.05  # s per step (Nav2 model_dt): horizon 2.8 s; call compute at 1/dt
    temperature: float = 0.3  # λ of the softmax weights (Nav2 temperature)
    accel_std: float = 2.0  # m/s², noise of sampled accelerations (integrated to speeds)
    w_rate_std: float = 1.5  # rad/s², noise of sampled yaw-rate changes (integrated)
    v_max: float = 5.5  # m/s
    v_min: float = 0.0  # m/s; negative allows reversing
    w_max: float = 1.9  # rad/s (Nav2 wz_max); the turning radius usually binds first
    speed_time_constant_s: float = 0.5  # s, τ_v of the vehicle's speed loop (0: ideal)
    accel_max: float = 3.0  # m/s², limit on the commanded speed's rise
    decel_max: float = 5.0  # m/s², limit on its fall
    target_speed: float = 5.0  # m/s, the paper's commanded speed
    goal_decel: float = 1.0  # m/s², v_ref = min(target, √(2·a·d_remaining)) near the goal
    goal_radius_m: float = 4.0  # remaining path length at which the goal critic turns on
    lateral_accel_max: float = 4.0  # m/s², |v·ω| above this is penalised
    smoothing_window: int = 9  # Savitzky–Golay window on the optimal ω (Nav2); < 3 disables
    path_resolution_m: float = 0.5  # the path is resampled to this spacing
    path_point_step: int = 4  # every n-th step is scored against the path (Nav2: 4)
    collision_radius_m: float = 1.2  # clearance below which a footprint circle collides
    inflation_radius_m: float = 3.0  # clearance below which the occupancy critic rises
    footprint_offsets_m: tuple[float, ...] = (0.0,)  # circle centres ahead of the pose
    # Critic weights.
    path_weight: float = 6.0  # mean cross-track distance [m]
    path_angle_weight: float = 4.0  # mean 1 − cos(yaw − path yaw)
    speed_weight: float = 20.0  # mean ((v − v_ref) / target_speed)²
    goal_weight: float = 2.0  # mean distance to the goal [m], within goal_radius_m
    collision_weight: float = 1000.0  # (any step collides) + fraction of colliding steps
    inflation_weight: float = 3.0  # mean closeness to occupied cells, 0..1
    constraint_weight: float = 4.0  # lateral acceleration excess and reversing
    # Terrain critic (ours; the paper's controller has none): mean over the steps of the
    # directional cost at the body centre, C(1 + βC) as the planner amplifies it. 0 = off.
    terrain_weight: float = 0.0  # weight of mean_t C(1 + β_c C), needs a costmap
    terrain_beta: float = 150.0  # β_c (the planner's default β, PlannerConfig.beta)
    # Against crawling and rolling (ours; 0 = off, the paper's controller: docs/controller.md).
    breakaway_speed_mps: float = 0.0  # the model stands still while |v_cmd| is below this
    roll_limit_fraction: float = 0.0  # slow corners to this × the vehicle's rollover a_lat
    # Biased sampling (ours, control/ancillary.py): this share of the samples is drawn
    # around a pure-pursuit rollout along the plan instead of the warm start. 0 = off.
    ancillary_fraction: float = 0.0
    ancillary_lookahead_m: float = 6.0  # pure pursuit's look-ahead distance l_d [m]

    def __post_init__(self) -> None:
        check_section(self, "mppi")  # each field's rule (core/constraints.py)

    @property
    def horizon_s(self) -> float:
        """Length of a rollout [s]."""
        return self.time_steps * self.model_dt


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
}
TERRAIN: dict[str, object] = {**ROBUST, "terrain_weight": 0.05}  # docs/controller.md

PRESET_FIELDS: frozenset[str] = frozenset(ROBUST) | frozenset(TERRAIN)
"""Every :class:`MPPIConfig` field a preset sets."""


def controller_settings(name: str) -> dict[str, object]:
    """The :class:`MPPIConfig` fields the named controller changes (none for ``"paper"``)."""
    if name not in CONTROLLERS:
        raise ValueError(f"unknown controller {name!r}; valid: {', '.join(CONTROLLERS)}")
    return {"paper": {}, "robust": dict(ROBUST), "terrain": dict(TERRAIN)}[name]


def with_controller(mppi: MPPIConfig, name: str) -> MPPIConfig:
    """``mppi`` with the named preset in place of any other: every field a preset sets back
    at its default, then ``name``'s; the other fields (the sample count) as they were."""
    paper = MPPIConfig()
    reset = {f.name: getattr(paper, f.name) for f in fields(MPPIConfig) if f.name in PRESET_FIELDS}
    return replace(mppi, **{**reset, **controller_settings(name)})


def mppi_before_overrides(mppi: MPPIConfig, overrides: Mapping[str, object]) -> MPPIConfig:
    """The ``mppi`` section a set of overrides starts from: the preset a new
    ``experiments.controller`` names, else ``mppi`` as it is. Raises
    :class:`InvalidSettingError` for a change to a field each drive sets from its vehicle
    (:data:`~dgt_lib.core.constraints.FROM_THE_VEHICLE`)."""
    given = {k.strip(): v for k, v in overrides.items()}
    for key in set(given) & set(FROM_THE_VEHICLE):
        now, value = getattr(mppi, key.partition(".")[2]), given[key]
        if value != now and str(value).strip() != format_setting(now):  # (as typed: "0.0")
            raise InvalidSettingError(f"{key}={format_setting(value)} is not allowed: "
                                      f"{key} is {FROM_THE_VEHICLE_TEXT}")
    named = given.get("experiments.controller")
    if isinstance(named, str) and named.strip() in CONTROLLERS:
        return with_controller(mppi, named.strip())
    return mppi
