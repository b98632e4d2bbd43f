"""Plane-contact wrench inequalities (TO-OSF eq. 15, reaction-on-robot convention)."""

import numpy as np

from wbcbench.tasks.contacts import PlaneContact, stack_wrench_constraints

FOOT = PlaneContact("l_sole", x_range=(-0.075, 0.075), y_range=(-0.05, 0.05), mu=0.5, fmin=30.0)


def feasible(contact: PlaneContact, wrench: np.ndarray) -> bool:
    C, lower, upper = contact.wrench_constraints()
    r = C @ wrench
    return bool(np.all(r >= lower - 1e-12) and np.all(r <= upper + 1e-12))


def test_row_count_and_shape() -> None:
    C, lower, upper = FOOT.wrench_constraints()
    # normal, 4 friction facets, 2 yaw, 4 CoP
    assert C.shape == (11, 6)
    assert lower.shape == upper.shape == (11,)


def test_pure_normal_force_at_the_centre_is_feasible() -> None:
    assert feasible(FOOT, np.array([0, 0, 300.0, 0, 0, 0]))


def test_minimum_normal_force() -> None:
    assert not feasible(FOOT, np.array([0, 0, 29.0, 0, 0, 0]))
    assert FOOT.violation(np.array([0, 0, 29.0, 0, 0, 0]))["normal"] == 1.0


def test_cop_box_matches_moment_ratios() -> None:
    fz = 200.0
    # CoP x = −m_y / f_z, CoP y = m_x / f_z
    for cop_x, cop_y, ok in (
        (0.07, 0.0, True),
        (0.08, 0.0, False),
        (-0.08, 0.0, False),
        (0.0, 0.049, True),
        (0.0, -0.051, False),
    ):
        wrench = np.array([0, 0, fz, cop_y * fz, -cop_x * fz, 0])
        assert feasible(FOOT, wrench) is ok, (cop_x, cop_y)
        assert bool(FOOT.violation(wrench)["cop"] == 0.0) is ok


def test_friction_pyramid_is_inscribed_in_the_cone() -> None:
    rng = np.random.default_rng(0)
    fz = 100.0
    for _ in range(500):
        ft = rng.uniform(-60, 60, 2)
        wrench = np.array([ft[0], ft[1], fz, 0, 0, 0])
        if feasible(FOOT, wrench):
            assert np.hypot(*ft) <= FOOT.mu * fz + 1e-9
    # along a facet normal the pyramid reaches μ cos(π/4) f_z
    edge = FOOT.mu * np.cos(np.pi / 4) * fz
    assert feasible(FOOT, np.array([edge - 1e-6, 0, fz, 0, 0, 0]))
    assert not feasible(FOOT, np.array([edge + 1e-3, 0, fz, 0, 0, 0]))


def test_yaw_moment_bound() -> None:
    assert feasible(FOOT, np.array([0, 0, 100.0, 0, 0, 49.0]))
    assert not feasible(FOOT, np.array([0, 0, 100.0, 0, 0, -51.0]))


def test_stacking_is_block_diagonal() -> None:
    hand = PlaneContact("l_palm", x_range=(-0.005, 0.005), y_range=(-0.005, 0.005), mu=0.05)
    C, _, _ = stack_wrench_constraints([FOOT, hand])
    assert C.shape == (22, 12)
    assert np.all(C[:11, 6:] == 0) and np.all(C[11:, :6] == 0)
