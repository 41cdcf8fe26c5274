"""What values each setting may take: one table, checked whenever a
:class:`~dgt_lib.core.config.Profile` is made, so ``dgt reproduce --set``, ``dgt plan
--set``, a notebook's ``SETTINGS`` and :meth:`Profile.with_overrides` refuse a value that
cannot work before any stage runs (docs/reliability.md → Settings), with one line naming
the setting, the value and what is allowed.

:data:`SETTING_RULES` holds one :class:`Rule` per numeric or text setting (a bool fits
by its type alone); :data:`CROSS_RULES` the rules between two settings.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace

from dgt_lib.core.overrides import InvalidOverrideError, format_setting

HEAD_INITS: tuple[str, ...] = ("prior", "default")
LR_SCHEDULES: tuple[str, ...] = ("constant", "cosine")
SELECTIONS: tuple[str, ...] = ("best_val", "last")
CONV_TAPS: tuple[str, ...] = ("all", "live")
INPUTS: tuple[str, ...] = ("rgbd", "geometry", "rgb")
"""Valid ``TrainConfig.head_init``, ``lr_schedule``, ``selection``,
``conv_taps`` and ``inputs`` values (re-exported by :mod:`dgt_lib.core.config`; checked when
a ``TrainConfig`` is made, so ``--set`` fails at once)."""
VEHICLES: tuple[str, ...] = ("jeep", "vw_van", "mercedes_van", "carla_cola")
"""The four vehicles, in head order (docs/ARCHITECTURE.md → Conventions; re-exported by
:mod:`dgt_lib.core.config`)."""
BEV_COLOURS: tuple[str, ...] = ("observed", "shuffled")
"""Valid ``BEVConfig.colour`` values."""


class InvalidSettingError(InvalidOverrideError):
    """A setting whose value is out of its allowed range (:data:`SETTING_RULES`)."""


@dataclass(frozen=True)
class Rule:
    """``check(value)`` is True for an allowed value; ``allowed`` says which in words
    (the error message); ``outside`` is a value just outside the range (the tests)."""

    check: Callable[[object], bool]
    allowed: str
    outside: object


def _number(v: object) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def at_least(low: float, *, integer: bool = False) -> Rule:
    """``value ≥ low`` (finite)."""
    kind = "an integer" if integer else "a finite number"
    return Rule(lambda v: _number(v) and v >= low, f"{kind} ≥ {low:g}",
                low - 1 if integer else low - 1e-3)


def above(low: float) -> Rule:
    """``value > low`` (finite)."""
    return Rule(lambda v: _number(v) and v > low, f"a finite number > {low:g}", low)


def between(low: float, high: float, *, high_open: bool = False) -> Rule:
    """``low ≤ value ≤ high`` (``< high`` with ``high_open``)."""
    end = ")" if high_open else "]"
    return Rule(lambda v: _number(v) and low <= v and (v < high if high_open else v <= high),
                f"in [{low:g}, {high:g}{end}", high if high_open else high + 1e-3)


def count_up_to(high: int) -> Rule:
    """An integer in [1, ``high``]: a count that multiplies work or memory (:data:`BOUNDS`)."""
    return Rule(lambda v: isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= high,
                f"an integer in [1, {high:,}]", 0)


def at_most(high: float) -> Rule:
    """``value ≤ high`` (finite)."""
    return Rule(lambda v: _number(v) and v <= high, f"a finite number ≤ {high:g}", high + 1e-3)


def integer_in(low: int, high: int) -> Rule:
    """An integer in [``low``, ``high``]."""
    return Rule(lambda v: isinstance(v, int) and not isinstance(v, bool) and low <= v <= high,
                f"an integer in [{low:,}, {high:,}]", low - 1)


def within(low: float, high: float) -> Rule:
    """A finite number in [``low``, ``high``] (a size or resolution: :data:`BOUNDS`)."""
    return Rule(lambda v: _number(v) and low <= v <= high, f"in [{low:g}, {high:g}]",
                low / 2 if low > 0 else low - 1)


def above_up_to(low: float, high: float) -> Rule:
    """``low < value ≤ high``."""
    return Rule(lambda v: _number(v) and low < v <= high, f"in ({low:g}, {high:g}]", low)


def one_of(*choices: str) -> Rule:
    """One of ``choices``."""
    return Rule(lambda v: v in choices, "one of " + ", ".join(choices), "bogus")


def optional(rule: Rule) -> Rule:
    """None, or what ``rule`` allows."""
    return Rule(lambda v: v is None or rule.check(v), f"none or {rule.allowed}", rule.outside)


def each(rule: Rule, n: int) -> Rule:
    """A tuple of ``n`` values each allowed by ``rule``."""
    return Rule(lambda v: all(rule.check(x) for x in v), f"{n} values, each {rule.allowed}",
                (rule.outside,) * n)


def increasing_within(low: float, high: float) -> Rule:
    """A strictly increasing tuple inside the open range (low, high)."""
    def check(v: tuple) -> bool:
        return (all(_number(x) and low < x < high for x in v)
                and all(a < b for a, b in zip(v, v[1:], strict=False)))
    return Rule(check, f"increasing values in ({low:g}, {high:g})",
                (float(low), high - 1.0))


def episode_counts() -> Rule:
    """Runs per vehicle: 4 integers in [0, MAX_EPISODES], not all 0 (a vehicle may sit a
    collection out)."""
    return Rule(lambda v: all(isinstance(x, int) and 0 <= x <= MAX_EPISODES for x in v)
                and sum(v) > 0, f"4 integers in [0, {MAX_EPISODES:,}], not all 0", (-1, 1, 1, 1))


def distance_range() -> Rule:
    """A (shortest, longest) pair: 0 < shortest ≤ longest."""
    return Rule(lambda v: all(_number(x) for x in v) and 0 < v[0] <= v[1],
                "two finite numbers 0 < low ≤ high", (2.0, 1.0))


COUNT, POSITIVE, NON_NEGATIVE = at_least(1, integer=True), above(0), at_least(0)
MAX_GENERATED = 64  # generated training vehicles at most (each a head while training)

# Upper bounds, from what one machine (tens of GB of memory, tens of cores) holds; a value
# past one fails in one line here instead of an "Unable to allocate 279 PiB" later:
# - seeds: run seeds are seed … seed + seeds − 1 and trial i's is seed + i; everything
#   stays below 2³¹ (the int32 some generators take) with MAX_SEED + 2 · 10⁶.
# - a world is (size / resolution)² height cells and the BEV and costmaps grow with it:
#   HFIELD_RESOLUTION_M ≥ 0.05 m, WORLD_SIZE_M ≤ 2 km and MAX_WORLD_CELLS (the cross rule)
#   16 M cells (64 MB of float32 heights; × 8 headings × 4 B = 512 MB of costmap).
# - n_headings ≤ 64: K layers × 16 M cells × 4 B = 4 GB at the largest world.
# - counts of samples, trials, epochs, widths: 10–100× the paper profile's, where a run
#   takes days; MPPI's samples × its horizon × the state (8 B each) stay below 1 GB.
# - workers ≤ 256: each a process of about 300 MB (torch, MuJoCo), 77 GB in all.
MAX_SEED = 2**31 - 2_000_000
MAX_SEEDS = 1_000
MAX_WORKERS = 256
MAX_EPISODES = 10_000
HFIELD_RESOLUTION_M = (0.05, 10.0)
WORLD_SIZE_M = 2_000.0
MAX_WORLD_CELLS = 16_000_000
HEIGHTMAP_RESOLUTION_M = (1e-3, 100.0)
"""``--resolution`` of a heightmap file [m/pixel] (``dgt plan``, ``dgt costmap``)."""
SEED = Rule(lambda v: isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= MAX_SEED,
            f"an integer in [0, {MAX_SEED:,}]", -1)
BOUNDS: dict[str, Rule] = {
    "seeds": count_up_to(MAX_SEEDS), "workers": count_up_to(MAX_WORKERS),
    "worlds.hfield_resolution_m": within(*HFIELD_RESOLUTION_M),
    "worlds.training_size_m": above_up_to(0, WORLD_SIZE_M),
    "worlds.eval_size_m": above_up_to(0, WORLD_SIZE_M),
    "costmap.n_headings": count_up_to(64), "costmap.stride": each(count_up_to(64), 2),
    "costmap.batch_size": count_up_to(1 << 16), "costmap.slope_trials": count_up_to(100_000),
    "train.epochs": count_up_to(10_000), "train.batch_size": count_up_to(1 << 16),
    "train.width": count_up_to(1024), "train.fc_hidden": count_up_to(8192),
    "planner.theta_bins": count_up_to(720),
    "planner.max_expansions": count_up_to(100_000_000),
    "experiments.n_hill": count_up_to(100_000), "experiments.n_ridge": count_up_to(100_000),
    "experiments.n_eval_jeep": count_up_to(100_000),
    "experiments.n_eval_vw_van": count_up_to(100_000),
    # MPPI: samples × horizon × state (8 B) stay below 1 GB (see above)
    "mppi.batch_size": integer_in(2, 100_000), "mppi.time_steps": integer_in(2, 1_000),
    "ground_truth.cells": count_up_to(1_000_000),
}
"""The settings bounded above, each with its rule (its ``outside`` value is below it; the
tests try ``high + 1`` too)."""

FROM_THE_VEHICLE_TEXT = "set from each vehicle's footprint for every drive"
FROM_THE_VEHICLE: tuple[str, ...] = ("mppi.footprint_offsets_m", "mppi.collision_radius_m",
                                     "mppi.inflation_radius_m")
"""MPPI fields a drive takes from its vehicle (``mppi_config.vehicle_footprint``): shown by
``dgt settings``, refused by ``--set`` (a value there would not be the one driven)."""

SETTING_RULES: dict[str, Rule] = {
    "seed": SEED,
    "worlds.training_seed": SEED,
    "worlds.eval_seed": SEED,
    "collect.episodes": episode_counts(), "collect.episode_duration_s": POSITIVE,
    "collect.speed_mps": POSITIVE, "collect.immobilized_limit_s": POSITIVE,
    "collect.frame_spacing_m": POSITIVE, "collect.frame_max_depth_m": POSITIVE,
    "collect.patch_interval_s": POSITIVE, "collect.patch_start_s": NON_NEGATIVE,
    "collect.survey_altitude_m": POSITIVE, "collect.survey_overlap": between(0, 1, high_open=True),
    "train.learning_rate": POSITIVE,
    "train.patience": optional(COUNT), "train.head_init": one_of(*HEAD_INITS),
    "train.lr_schedule": one_of(*LR_SCHEDULES),
    "train.selection": one_of(*SELECTIONS), "train.conv_taps": one_of(*CONV_TAPS),
    "train.inputs": one_of(*INPUTS), "train.scarce_vehicle": one_of("none", *VEHICLES),
    "train.scarce_fraction": above_up_to(0, 1),
    "costmap.tau_s_margin": POSITIVE,
    "planner.step_m": POSITIVE, "planner.beta": NON_NEGATIVE,
    "planner.heuristic": one_of("euclidean", "cost_to_go"),  # navigation's HEURISTICS
    "planner.heuristic_weight": at_least(1), "planner.goal_tolerance_m": POSITIVE,
    "planner.goal_heading_tolerance_rad": above_up_to(0, math.pi),
    "planner.closed_cell_m": POSITIVE, "planner.substep_m": POSITIVE,
    "planner.max_time_s": POSITIVE,
    "experiments.start_jitter_m": NON_NEGATIVE, "experiments.heading_jitter_deg": between(0, 180),
    "experiments.eval_distance_m": distance_range(), "experiments.eval_min_hazard_m": NON_NEGATIVE,
    "experiments.time_limit_base_s": POSITIVE, "experiments.time_limit_factor": NON_NEGATIVE,
    "experiments.controller": one_of("paper", "robust", "terrain"),  # controller.CONTROLLERS
    "ground_truth.run_up_m": NON_NEGATIVE,
    "ground_truth.past_m": NON_NEGATIVE, "ground_truth.edge_margin_m": NON_NEGATIVE,
    "ground_truth.tree_clearance_m": NON_NEGATIVE, "ground_truth.max_slope_deg": above_up_to(0, 90),
    "ground_truth.slope_edges_deg": increasing_within(0, 90),
    "ground_truth.roughness_edge_m": POSITIVE,
    "ground_truth.contrast_threshold": between(0, 1, high_open=True), "ground_truth.seed": SEED,
    "bev.pose_sigma_xy_m": NON_NEGATIVE, "bev.pose_sigma_yaw_deg": between(0, 180),
    "bev.pose_drift_m": NON_NEGATIVE, "bev.colour": one_of(*BEV_COLOURS),
    "conditioned.generated_vehicles": Rule(
        lambda v: isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= MAX_GENERATED,
        f"an integer in [0, {MAX_GENERATED}]", MAX_GENERATED + 1),
    **{f"mppi.{name}": POSITIVE for name in (
        "model_dt", "temperature", "v_max", "w_max", "accel_max", "decel_max", "target_speed",
        "goal_decel", "lateral_accel_max", "path_resolution_m", "ancillary_lookahead_m")},
    **{f"mppi.{name}": NON_NEGATIVE for name in (
        "accel_std", "w_rate_std", "speed_time_constant_s", "goal_radius_m", "path_weight",
        "path_angle_weight", "speed_weight", "goal_weight", "collision_weight",
        "inflation_weight", "constraint_weight", "terrain_weight", "terrain_beta",
        "breakaway_speed_mps", "roll_limit_fraction")},
    "mppi.v_min": at_most(0), "mppi.smoothing_window": at_least(0, integer=True),
    "mppi.path_point_step": COUNT, "mppi.ancillary_fraction": between(0, 1, high_open=True),
    **{name: Rule(check, FROM_THE_VEHICLE_TEXT, outside) for name, check, outside in (
        ("mppi.footprint_offsets_m", lambda v: len(v) > 0 and all(_number(x) for x in v), ()),
        ("mppi.collision_radius_m", lambda v: _number(v) and v > 0, 0.0),
        ("mppi.inflation_radius_m", lambda v: _number(v) and v > 0, 0.0))},
    **BOUNDS,  # the settings bounded above
}
"""Every setting's allowed values, by dotted name (``dgt settings`` lists the names)."""


@dataclass(frozen=True)
class CrossRule:
    """A rule between settings: ``check(profile)`` is True when they agree; ``breaking``
    is an override set that breaks it from any shipped profile (the tests)."""

    names: tuple[str, ...]
    check: Callable[[object], bool]
    allowed: str
    breaking: dict[str, object]


CROSS_RULES: tuple[CrossRule, ...] = (
    CrossRule(("worlds.training_size_m", "worlds.eval_size_m", "worlds.hfield_resolution_m"),
              lambda p: (max(p.worlds.training_size_m, p.worlds.eval_size_m)
                         / p.worlds.hfield_resolution_m) ** 2 <= MAX_WORLD_CELLS,
              f"a world has at most {MAX_WORLD_CELLS:,} height cells ((size / resolution)²)",
              {"worlds.training_size_m": 1000.0, "worlds.hfield_resolution_m": 0.1}),
    CrossRule(("planner.substep_m", "planner.step_m"),
              lambda p: p.planner.substep_m <= p.planner.step_m,
              "the collision-check spacing is at most one primitive",
              {"planner.substep_m": 2.0, "planner.step_m": 1.0}),
    CrossRule(("ground_truth.slope_edges_deg", "ground_truth.max_slope_deg"),
              lambda p: p.ground_truth.slope_edges_deg[-1] < p.ground_truth.max_slope_deg,
              "the slope strata end below the steepest cell sampled",
              {"ground_truth.slope_edges_deg": "4,10,18", "ground_truth.max_slope_deg": 18.0}),
    CrossRule(("mppi.ancillary_fraction", "mppi.accel_std", "mppi.w_rate_std"),
              lambda p: p.mppi.ancillary_fraction == 0 or min(p.mppi.accel_std,
                                                              p.mppi.w_rate_std) > 0,
              "biased sampling needs noise around its rollout",
              {"mppi.ancillary_fraction": 0.1, "mppi.w_rate_std": 0.0}),
    CrossRule(("train.scarce_fraction", "train.scarce_vehicle"),
              lambda p: not 0 < p.train.scarce_fraction < 1 or p.train.scarce_vehicle != "none",
              "a fraction of the runs below 1 names whose runs to thin out",
              {"train.scarce_fraction": 0.3}),
)


def _value(profile: object, name: str) -> object:
    section, _, field_ = name.rpartition(".")
    return getattr(getattr(profile, section) if section else profile, field_)


def check_section(section: object, name: str) -> None:
    """Raise :class:`InvalidSettingError` for the first field of a settings object outside
    its :data:`SETTING_RULES` entry (``name`` is its section, e.g. ``"mppi"``), or for the
    first broken :data:`CROSS_RULES` entry between its own fields: what a section made on
    its own (``MPPIConfig(temperature=0)``) is checked against, too."""
    prefix = name + "."
    for setting, rule in SETTING_RULES.items():
        if setting.startswith(prefix):
            value = getattr(section, setting[len(prefix):])
            if not rule.check(value):
                raise InvalidSettingError(f"{setting}={format_setting(value)} is not allowed: "
                                          f"{setting} must be {rule.allowed}")
    _check_cross(SimpleNamespace(**{name: section}),
                 [r for r in CROSS_RULES if all(n.startswith(prefix) for n in r.names)])


def _check_cross(profile: object, rules: list[CrossRule] | tuple[CrossRule, ...]) -> None:
    for rule in rules:
        if not rule.check(profile):
            given = ", ".join(f"{n}={format_setting(_value(profile, n))}" for n in rule.names)
            raise InvalidSettingError(f"{given} do not fit together: {rule.allowed}")


def check_settings(profile: object) -> None:
    """Raise :class:`InvalidSettingError` for the first setting of ``profile`` outside
    :data:`SETTING_RULES` or the first broken :data:`CROSS_RULES` entry."""
    for name, rule in SETTING_RULES.items():
        value = _value(profile, name)
        if not rule.check(value):
            raise InvalidSettingError(f"{name}={format_setting(value)} is not allowed: "
                                      f"{name} must be {rule.allowed}")
    _check_cross(profile, CROSS_RULES)
