import numpy as np
import pytest

from dgt_lib.core.geometry import GridSpec
from dgt_lib.mapping.baselines import (
    SlopeModel,
    binary_costmap,
    fit_slope_model,
    forward_slope,
    isotropic_costmap,
    slope_costmap,
)
from dgt_lib.perception.patches import extract_patches
from tests.test_costmap import synthetic_bev


def test_isotropic_is_the_mean_over_headings():
    cost = np.random.default_rng(0).random((8, 5, 6)).astype(np.float32)
    iso = isotropic_costmap(cost)
    assert iso.shape == (1, 5, 6)
    np.testing.assert_allclose(iso[0], cost.mean(axis=0), rtol=1e-6)
    assert isotropic_costmap(cost[None]).shape == (1, 1, 5, 6)
    assert not binary_costmap((5, 6)).any()


def test_forward_slope_of_a_ramp_depends_on_heading():
    grid = GridSpec((0.0, 0.0), 0.4, (60, 60))
    x, _ = grid.cell_centers()
    bev = synthetic_bev((0.2 * x).astype(np.float32))
    poses = np.array([[12.0, 12.0, 0.0], [12.0, 12.0, np.pi], [12.0, 12.0, np.pi / 2]])
    patches, observed = extract_patches(bev, poses)
    theta = forward_slope(patches, observed)
    np.testing.assert_allclose(theta, [np.arctan(0.2), -np.arctan(0.2), 0.0], atol=1e-4)
    np.testing.assert_allclose(forward_slope(patches), theta, atol=1e-6)


def test_slope_model_shape_and_constraints():
    m = SlopeModel(theta0=0.0, theta_min=-0.5, theta_max=0.3, p_u=2.0, p_d=1.0)
    L = m.locomotion(np.array([0.0, 0.15, 0.3, 0.4, -0.25, -0.6]))
    np.testing.assert_allclose(L, [1.0, 0.75, 0.0, 0.0, 0.5, 0.0], atol=1e-6)
    with pytest.raises(ValueError):
        SlopeModel(theta0=0.5, theta_min=-0.5, theta_max=0.3, p_u=2.0, p_d=1.0)


def test_optuna_fit_recovers_a_known_model_and_is_seeded():
    truth = SlopeModel(theta0=0.05, theta_min=-0.6, theta_max=0.35, p_u=2.0, p_d=3.0)
    theta = np.random.default_rng(1).uniform(-0.7, 0.5, 2000)
    labels = truth.locomotion(theta)
    fit = fit_slope_model(theta, labels, n_trials=150, seed=3)
    assert np.mean((fit.locomotion(theta) - labels) ** 2) < 0.01
    assert abs(fit.theta_max - truth.theta_max) < 0.08
    assert fit == fit_slope_model(theta, labels, n_trials=150, seed=3)


def test_slope_costmap_costs_more_uphill_for_a_weak_climber():
    grid = GridSpec((0.0, 0.0), 0.4, (70, 70))
    x, _ = grid.cell_centers()
    bev = synthetic_bev((0.3 * x).astype(np.float32))  # ~17° ramp rising toward +x
    weak = SlopeModel(theta0=0.0, theta_min=-0.6, theta_max=0.25, p_u=1.0, p_d=2.0)
    strong = SlopeModel(theta0=0.0, theta_min=-0.8, theta_max=0.7, p_u=2.0, p_d=2.0)
    cost = slope_costmap(bev, [weak, strong], 8, progress=False)
    centre = (slice(27, 43), slice(27, 43))
    up, down = cost[0, 0][centre].mean(), cost[0, 4][centre].mean()
    assert up > 0.95 and down < 0.4  # weak climber: uphill impassable, downhill fine
    assert cost[1, 0][centre].mean() < up - 0.5


def test_ctrl_c_during_the_slope_fit_stops_it_without_a_traceback(capfd, monkeypatch):
    """Optuna would log an interrupted trial as a failure with its traceback."""
    calls = []
    real = SlopeModel.locomotion

    def interrupted(self, theta):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(self, theta)

    monkeypatch.setattr(SlopeModel, "locomotion", interrupted)
    theta = np.linspace(-0.3, 0.3, 50)
    with pytest.raises(KeyboardInterrupt):
        fit_slope_model(theta, np.clip(1 - theta, 0, 1), n_trials=10)
    out, err = capfd.readouterr()
    assert len(calls) == 3 and "Traceback" not in out + err
