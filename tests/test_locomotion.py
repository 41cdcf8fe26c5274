"""Locomotion labels: the paper's formula and its sliding window over a run."""

import numpy as np
import pytest

from dgt_lib.perception.locomotion import TARGET_SPEED_MPS, locomotion, locomotion_signal


def straight_run(speeds_mps: np.ndarray, dt: float = 0.04, heading: float = 0.3):
    """Positions of a vehicle driving straight at piecewise speeds (one per sample)."""
    t = np.arange(len(speeds_mps)) * dt
    s = np.concatenate([[0.0], np.cumsum(speeds_mps[:-1] * dt)])
    pos = np.stack([s * np.cos(heading), s * np.sin(heading), 0.1 * s], axis=1)
    return t, pos


def test_full_speed_is_one_and_stopped_is_exp_minus_4_5():
    assert locomotion(5.0, 1.0) == pytest.approx(1.0)
    assert locomotion(0.0, 1.0) == pytest.approx(np.exp(-4.5))
    assert locomotion(2.5, 1.0) == pytest.approx(np.exp(-0.5 * 0.5**2 / (1 / 3) ** 2))


def test_monotone_in_speed_up_to_target_and_symmetric_above():
    speeds = np.linspace(0.0, TARGET_SPEED_MPS, 51)
    values = locomotion(speeds * 0.8, 0.8)
    assert np.all(np.diff(values) > 0)
    # Paper's formula is symmetric in the speed ratio: 7.5 m/s scores like 2.5 m/s.
    assert locomotion(7.5, 1.0) == pytest.approx(locomotion(2.5, 1.0))


def test_locomotion_rejects_bad_input():
    with pytest.raises(ValueError):
        locomotion(1.0, 0.0)
    with pytest.raises(ValueError):
        locomotion(-1.0, 1.0)


def test_signal_constant_speed_and_stopped_runs():
    n = 200
    t, pos = straight_run(np.full(n, 5.0))
    assert np.allclose(locomotion_signal(t, pos), 1.0)
    t, pos = straight_run(np.zeros(n))
    assert np.allclose(locomotion_signal(t, pos), np.exp(-4.5))


def test_signal_uses_planar_displacement():
    # Climbing at 5 m/s ground speed is full locomotion even though 3-D speed is higher.
    t, pos = straight_run(np.full(100, 5.0))
    pos[:, 2] = 0.5 * np.hypot(pos[:, 0], pos[:, 1])
    assert np.allclose(locomotion_signal(t, pos), 1.0)


def test_signal_localises_a_stop_and_handles_run_ends():
    dt, window = 0.04, 1.0
    speeds = np.full(500, 5.0)
    speeds[200:300] = 0.0  # stuck from 8 s to 12 s
    t, pos = straight_run(speeds, dt)
    L = locomotion_signal(t, pos, window_s=window)
    assert L.shape == t.shape
    # Windows entirely inside the stop see no motion, windows far from it full speed.
    assert np.allclose(L[(t > 8.6) & (t < 11.4)], np.exp(-4.5))
    far = (t < 7.4) | (t > 12.6)
    assert np.allclose(L[far], 1.0)  # includes the first and last samples (shifted windows)
    # Entering the stop, L falls monotonically.
    entering = (t > 7.5) & (t < 8.5)
    assert np.all(np.diff(L[entering]) <= 1e-12)
    assert np.all((L >= 0) & (L <= 1))


def test_signal_irregular_sampling_and_short_run():
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 10, 300))
    pos = np.stack([3.0 * t, np.zeros_like(t)], axis=1)  # 3 m/s, 2-D positions
    assert np.allclose(locomotion_signal(t, pos), locomotion(3.0, 1.0))
    short_t = np.array([0.0, 0.2, 0.4])
    short = np.stack([5 * short_t, 0 * short_t], axis=1)
    assert np.allclose(locomotion_signal(short_t, short, window_s=1.0), 1.0)


def test_signal_rejects_bad_runs():
    with pytest.raises(ValueError):
        locomotion_signal(np.array([0.0]), np.zeros((1, 2)))
    with pytest.raises(ValueError):
        locomotion_signal(np.array([0.0, 1.0, 1.0]), np.zeros((3, 2)))
    with pytest.raises(ValueError):
        locomotion_signal(np.array([0.0, 1.0]), np.zeros((3, 2)))


def test_signal_at_query_times_matches_samples():
    speeds = np.concatenate([np.full(150, 5.0), np.full(150, 1.0)])
    t, pos = straight_run(speeds)
    full = locomotion_signal(t, pos)
    assert np.allclose(locomotion_signal(t, pos, at_s=t[::7]), full[::7])
    mid = locomotion_signal(t, pos, at_s=np.array([2.0, 9.0, 50.0]))  # 50 s: clipped to the end
    assert mid[0] == pytest.approx(1.0) and mid[1] == pytest.approx(locomotion(1.0, 1.0))
    assert mid[2] == pytest.approx(mid[1])
