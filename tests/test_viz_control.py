"""Figures of MPPI path tracking (dgt_lib.viz.control)."""

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from dgt_lib.core.controller import MPPIConfig  # noqa: E402
from dgt_lib.core.geometry import GridSpec  # noqa: E402
from dgt_lib.navigation.control.mppi import MPPIController, warm_start_trace  # noqa: E402
from dgt_lib.viz import control as viz_control  # noqa: E402


def test_effective_samples_counts_what_the_average_rests_on():
    assert viz_control.effective_samples(np.full(8, 1 / 8)) == pytest.approx(8.0)
    assert viz_control.effective_samples(np.array([1.0, 0.0, 0.0])) == pytest.approx(1.0)
    assert viz_control.effective_samples(np.array([0.5, 0.5, 0.0])) == pytest.approx(2.0)


def test_the_figures_draw_one_call_and_leave_colliding_samples_out():
    grid = GridSpec((-5.0, -10.0), 0.4, (50, 100))
    X, Y = grid.cell_centers()
    occ = (np.hypot(X - 8.0, Y - 1.0) < 1.0).astype(np.uint8)
    path = np.stack([np.linspace(0, 30, 61), np.zeros(61), np.zeros(61)], axis=1)
    cfg = MPPIConfig(batch_size=64)
    ctrl = MPPIController(cfg, wheelbase_m=2.46, max_steer_rad=math.radians(35), seed=0,
                          backend="numpy")
    ctrl.keep_rollouts = True
    ctrl.set_path(path)
    ctrl.compute((0.0, 0.0, 0.0), 4.0, occ, grid)
    r = ctrl.last_rollouts
    fig, axes = plt.subplots(2, 3)
    viz_control.plot_rollouts(axes[0, 0], r, 0.3, path, occ, grid, ctrl.optimal_trajectory,
                              n_show=20)
    assert len(axes[0, 0].lines) == 20 + 2  # the heaviest samples, the path, the plan
    viz_control.plot_critic_terms(axes[0, 1], r, cfg.collision_weight)
    hit = int((r.cost >= cfg.collision_weight).sum())
    assert hit > 0 and axes[0, 1].get_title().startswith(f"{hit} of 64")
    viz_control.plot_weights(axes[0, 2], r.cost)
    assert len(axes[0, 2].lines) == 3
    trace = warm_start_trace(ctrl, (0.0, 0.0, 0.0), 0.0, 5)
    viz_control.plot_warm_start_trace(axes[1, 0], trace, cfg.model_dt)
    t = np.arange(5) * 0.05
    viz_control.plot_drive(axes[1, 1:], t, np.zeros((5, 2)), path, t, t, t)
    assert len(axes[1, 2].lines) == 3
    plt.close(fig)
