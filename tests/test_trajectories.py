"""Reference trajectories: values at the knots, and derivatives against finite differences."""

import numpy as np
import pytest

from wbcbench.tasks import trajectories as tr

CASES = {
    "sinusoid": tr.Sinusoid(np.array([0.02, -0.01]), frequency=0.4, t0=1.0, phase=0.3),
    "spline": tr.spline_there_and_back(2.0, 6.0, np.array([0.025, 0.0, 0.01])),
    "spline_one_way": tr.spline_there_and_back(2.0, 6.0, np.array([0.1]), symmetric=False),
    "min_jerk": tr.MinimumJerk(np.array([1.0, 2.0, 4.0]), np.array([[0.0], [0.15], [-0.05]])),
    "piecewise_cubic": tr.PiecewiseCubic(np.array([0.0, 1.0, 2.5]), np.array([0.0, 0.3, 0.1])),
}


@pytest.mark.parametrize("name", CASES)
def test_derivatives_match_finite_differences(name: str) -> None:
    traj = CASES[name]
    eps = 1e-6
    for t in np.linspace(0.05, 7.95, 97):
        _, xd, xdd = traj.sample(t)
        xp, xdp, _ = traj.sample(t + eps)
        xm, xdm, _ = traj.sample(t - eps)
        np.testing.assert_allclose(xd, (xp - xm) / (2 * eps), atol=1e-6)
        np.testing.assert_allclose(xdd, (xdp - xdm) / (2 * eps), atol=1e-5)


def test_spline_there_and_back_hits_plus_and_minus_amplitude_and_returns() -> None:
    a = np.array([0.025, 0.0, 0.0])
    traj = tr.spline_there_and_back(10.0, 12.0, a)
    for t, expected in ((9.0, 0 * a), (10.5, a), (11.5, -a), (12.0, 0 * a), (13.0, 0 * a)):
        np.testing.assert_allclose(traj.sample(t)[0], expected, atol=1e-15)
    # rest at both ends
    np.testing.assert_allclose(traj.sample(10.0)[1], 0.0, atol=1e-15)
    np.testing.assert_allclose(traj.sample(12.0)[1], 0.0, atol=1e-15)


def test_min_jerk_rests_at_waypoints() -> None:
    traj = CASES["min_jerk"]
    for t, value in ((1.0, 0.0), (2.0, 0.15), (4.0, -0.05)):
        x, xd, xdd = traj.sample(t)
        np.testing.assert_allclose(x, [value], atol=1e-15)
        np.testing.assert_allclose(xd, [0.0], atol=1e-12)
        np.testing.assert_allclose(xdd, [0.0], atol=1e-9)


def test_sinusoid_is_zero_and_continuous_at_start() -> None:
    traj = CASES["sinusoid"]
    np.testing.assert_allclose(traj.sample(0.5)[0], 0.0)
    np.testing.assert_allclose(traj.sample(1.0)[0], 0.0, atol=1e-15)


def test_piecewise_linear_interpolates() -> None:
    traj = tr.PiecewiseLinear(np.array([0.0, 2.0]), np.array([[0.0, 1.0], [2.0, 3.0]]))
    x, xd, xdd = traj.sample(0.5)
    np.testing.assert_allclose(x, [0.5, 1.5])
    np.testing.assert_allclose(xd, [1.0, 1.0])
    np.testing.assert_allclose(xdd, [0.0, 0.0])
