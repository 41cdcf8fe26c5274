"""Settings of the MPPI tracker (Nav2's defaults, scaled to the paper's 5 m/s) and the
footprint a vehicle gives it."""

from __future__ import annotations

from dataclasses import dataclass, fields

from dgt_lib.core.vehicle_spec import footprint_circles


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
    first_step_weight: float = 0.0  # ((v_0 − v_ref) / target_speed)² of the sent step
    roll_limit_fraction: float = 0.0  # slow corners to this × the vehicle's rollover a_lat
    corner_accel_mps2: float = 0.0  # v_ref ≤ √(a/|κ|) of the plan's corners, braked into
                                    # at goal_decel (reference_path.corner_speed_cap); 0 = off
    # Biased sampling (ours, control/ancillary.py): this share of the samples is drawn
    # around a pure-pursuit rollout along the plan instead of the warm start. 0 = off.
    ancillary_fraction: float = 0.0
    ancillary_lookahead_m: float = 6.0  # pure pursuit's look-ahead distance l_d [m]

    def __post_init__(self):
        if self.batch_size < 2 or self.time_steps < 2 or self.model_dt <= 0:
            raise ValueError("MPPIConfig needs batch_size ≥ 2, time_steps ≥ 2, model_dt > 0")
        if self.temperature <= 0:
            raise ValueError(f"temperature must be > 0, got {self.temperature}")
        if not self.v_min <= 0.0 < self.v_max:
            raise ValueError(f"need v_min ≤ 0 < v_max, got {self.v_min}, {self.v_max}")
        if self.path_point_step < 1 or self.path_resolution_m <= 0:
            raise ValueError("path_point_step must be ≥ 1 and path_resolution_m > 0")
        if not 0 < self.collision_radius_m < self.inflation_radius_m:
            raise ValueError("need 0 < collision_radius_m < inflation_radius_m")
        if self.terrain_weight < 0 or self.terrain_beta < 0:
            raise ValueError("terrain_weight and terrain_beta must be ≥ 0")
        if min(self.breakaway_speed_mps, self.first_step_weight, self.roll_limit_fraction,
               self.corner_accel_mps2) < 0:
            raise ValueError("breakaway_speed_mps, first_step_weight, roll_limit_fraction and "
                             "corner_accel_mps2 must be ≥ 0")
        if not 0 <= self.ancillary_fraction < 1 or self.ancillary_lookahead_m <= 0:
            raise ValueError("need 0 ≤ ancillary_fraction < 1 and ancillary_lookahead_m > 0, "
                             f"got {self.ancillary_fraction}, {self.ancillary_lookahead_m}")
        if self.ancillary_fraction > 0 and min(self.accel_std, self.w_rate_std) <= 0:
            raise ValueError("ancillary_fraction > 0 needs accel_std > 0 and w_rate_std > 0")

    @property
    def horizon_s(self) -> float:
        """Length of a rollout [s]."""
        return self.time_steps * self.model_dt


def vehicle_footprint(vehicle, margin_m: float = 0.2) -> dict[str, object]:
    """Footprint circles for the occupancy critic from a ``VehicleSpec``-like object
    (``wheelbase_m``, ``length_m``, ``width_m``), as :class:`MPPIConfig` fields::

        cfg = dataclasses.replace(MPPIConfig(), **vehicle_footprint(spec))

    The planner's circles (:func:`dgt_lib.core.vehicle_spec.footprint_circles`, covering the
    length × width rectangle around the body centre) moved to the rear-axle
    reference (the body centre is ℓ/2 ahead of it, equal overhangs), radius plus
    ``margin_m``; the inflation radius is set 1.5 m beyond it.
    """
    offsets, radius = footprint_circles(vehicle.length_m, vehicle.width_m)
    radius += margin_m
    offsets = offsets + 0.5 * vehicle.wheelbase_m
    return {
        "footprint_offsets_m": tuple(round(float(o), 3) for o in offsets),
        "collision_radius_m": radius,
        "inflation_radius_m": radius + 1.5,
    }


def parse_mppi_settings(text: str) -> dict[str, object]:
    """``"lateral_accel_max=2.0,w_rate_std=0.75"`` → :class:`MPPIConfig` fields for
    ``drive(mppi_settings=…)``, each typed by its default (``20`` for a float field is
    20.0). Raises ValueError naming the valid fields for anything else."""
    defaults = MPPIConfig()
    out: dict[str, object] = {}
    for part in text.split(","):
        name, _, value = (p.strip() for p in part.partition("="))
        if not name or not value or not hasattr(defaults, name):
            raise ValueError(f"{part.strip()!r} is not FIELD=VALUE of an MPPI setting; fields: "
                             f"{', '.join(f.name for f in fields(MPPIConfig))}")
        out[name] = type(getattr(defaults, name))(value)
    return out
