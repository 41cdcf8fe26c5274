"""Validation of the planner's configuration and maps."""

from __future__ import annotations

import numpy as np

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.navigation.planner.heuristics import HEURISTICS


def check_config(cfg: PlannerConfig) -> None:
    """Raise ValueError for a :class:`PlannerConfig` the planner cannot use."""
    if cfg.heuristic not in HEURISTICS:
        raise ValueError(f"heuristic must be one of {HEURISTICS}, got {cfg.heuristic!r}")
    positive = ("step_m", "goal_tolerance_m", "goal_heading_tolerance_rad", "max_time_s",
                "closed_cell_m", "substep_m")
    for name in positive:
        if not getattr(cfg, name) > 0:
            raise ValueError(f"PlannerConfig.{name} must be > 0, got {getattr(cfg, name)}")
    if cfg.heuristic_weight < 1:
        raise ValueError(f"PlannerConfig.heuristic_weight must be ≥ 1, got {cfg.heuristic_weight}")
    if cfg.beta < 0:
        raise ValueError(f"PlannerConfig.beta must be ≥ 0, got {cfg.beta}")
    if cfg.theta_bins < 1 or cfg.max_expansions < 1:
        raise ValueError("PlannerConfig.theta_bins and max_expansions must be ≥ 1")
    if cfg.shot_distance_m < 0:
        raise ValueError(f"PlannerConfig.shot_distance_m must be ≥ 0, got {cfg.shot_distance_m}")
    if cfg.safety_margin_m < 0:
        raise ValueError(f"PlannerConfig.safety_margin_m must be ≥ 0, got {cfg.safety_margin_m}")


def check_maps(costmap: np.ndarray, occupancy: np.ndarray, grid: GridSpec) -> None:
    """Raise ValueError unless costmap is (K, H, W) in [0, 1] and occupancy (H, W) in
    {0, 1, 2}, (H, W) = ``grid.shape``."""
    if costmap.ndim != 3 or costmap.shape[1:] != grid.shape:
        raise ValueError(
            f"costmap must be (K, H, W) with (H, W) = {grid.shape}, got {costmap.shape}"
        )
    if not np.all(np.isfinite(costmap)) or costmap.min() < 0 or costmap.max() > 1:
        raise ValueError("costmap values must be finite and in [0, 1]")
    if occupancy.shape != grid.shape:
        raise ValueError(f"occupancy must be (H, W) = {grid.shape}, got {occupancy.shape}")
    if not np.isin(occupancy, (0, 1, 2)).all():
        raise ValueError("occupancy values must be 0 (free), 1 (occupied) or 2 (unobserved)")
