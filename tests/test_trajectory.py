"""wbc.trajectory building blocks: quintic segments (eqs. 7-9 of Lu et al.), line and arc
pose paths with geodesic orientation and quintic timing, DLS IK, flip detection."""

import numpy as np
import pinocchio as pin
import pytest

import wbc
from wbc.analysis.singularity import singularity_measure
from wbc.core.errors import InvalidInputError
from wbc.trajectory import (
    ArcPath,
    JointTrajectory,
    LinePath,
    Quintic,
    SubPath,
    TimedPath,
    branch_switches,
    rest_to_rest_duration,
    solve_ik,
    wrist_flips,
)


@pytest.fixture(scope="module")
def puma():
    return wbc.load_robot("puma560")


def random_pose(rng):
    pose = np.eye(4)
    pose[:3, :3] = pin.exp3(rng.normal(size=3))
    pose[:3, 3] = rng.uniform(-1.0, 1.0, 3)
    return pose


# ------------------------------------------------------------------------------- quintic
def test_quintic_meets_all_six_boundary_conditions_exactly(rng):
    for _ in range(20):
        start, end = rng.normal(size=(3, 4)), rng.normal(size=(3, 4))
        duration = rng.uniform(0.1, 10.0)
        segment = Quintic(start, end, duration)
        for t, expected in ((0.0, start), (duration, end)):
            for value, wanted in zip(segment(t), expected, strict=True):
                np.testing.assert_allclose(value, wanted, rtol=1e-9, atol=1e-9)


def test_quintic_coefficients_solve_the_matrix_form_of_eq8(rng):
    start, end, duration = rng.normal(size=3), rng.normal(size=3), 2.7
    T = duration
    matrix = np.array([  # rows: F(0), F(T), F'(0), F'(T), F''(0), F''(T) over (A, B, C, D, E, F)
        [0, 0, 0, 0, 0, 1], [T**5, T**4, T**3, T**2, T, 1],
        [0, 0, 0, 0, 1, 0], [5 * T**4, 4 * T**3, 3 * T**2, 2 * T, 1, 0],
        [0, 0, 0, 2, 0, 0], [20 * T**3, 12 * T**2, 6 * T, 2, 0, 0]])
    rhs = [start[0], end[0], start[1], end[1], start[2], end[2]]
    np.testing.assert_allclose(Quintic(start, end, duration).coefficients, np.linalg.solve(matrix, rhs), rtol=1e-10)


def test_quintic_derivatives_are_consistent(rng):
    segment = Quintic(rng.normal(size=(3, 2)), rng.normal(size=(3, 2)), 1.5)
    h = 1e-6
    for t in np.linspace(0.1, 1.4, 7):
        np.testing.assert_allclose((segment(t + h)[0] - segment(t - h)[0]) / (2 * h), segment(t)[1], atol=1e-6)
        np.testing.assert_allclose((segment(t + h)[1] - segment(t - h)[1]) / (2 * h), segment(t)[2], atol=1e-6)


def test_rest_to_rest_peaks_and_duration():
    segment = Quintic.rest_to_rest(0.0, 1.0, 2.0)
    t = np.linspace(0.0, 2.0, 20001)
    states = np.array([segment(x) for x in t])
    assert np.all(np.diff(states[:, 0]) >= 0.0)
    assert states[:, 1].max() == pytest.approx(15 / 8 / 2.0, rel=1e-6)
    assert states[:, 2].max() == pytest.approx(10 / np.sqrt(3) / 4.0, rel=1e-6)
    duration = rest_to_rest_duration(0.3, max_speed=0.1, max_acceleration=0.05)
    fitted = Quintic.rest_to_rest(0.0, 0.3, duration)
    peaks = np.array([fitted(x)[1:] for x in np.linspace(0.0, duration, 20001)]).max(axis=0)
    assert peaks[0] <= 0.1 + 1e-12 and peaks[1] <= 0.05 + 1e-12
    assert max(peaks[0] / 0.1, peaks[1] / 0.05) == pytest.approx(1.0, rel=1e-6)  # one bound is tight


def test_quintic_holds_its_boundary_state_outside_its_interval():
    segment = Quintic.rest_to_rest([0.0, 1.0], [2.0, -1.0], 3.0)
    np.testing.assert_array_equal(segment(-1.0)[0], [0.0, 1.0])
    np.testing.assert_array_equal(segment(5.0)[0], [2.0, -1.0])


@pytest.mark.parametrize("start, end, duration", [
    ((0, 0, 0), (1, 0, 0), 0.0), ((0, 0, 0), (1, 0, 0), -1.0), ((0, 0), (1, 0, 0), 1.0),
    ((np.nan, 0, 0), (1, 0, 0), 1.0), ((np.zeros(2), 0, 0), (np.zeros(3), 0, 0), 1.0)])
def test_quintic_rejects_bad_input(start, end, duration):
    with pytest.raises(InvalidInputError):
        Quintic(start, end, duration)


# ------------------------------------------------------------------------------- paths
def finite_difference_twist(reference, t, h=1e-6):
    (before, _), (after, _) = reference(t - h), reference(t + h)
    linear = (after[:3, 3] - before[:3, 3]) / (2 * h)
    angular = pin.log3(after[:3, :3] @ before[:3, :3].T) / (2 * h)  # world-aligned
    return np.r_[linear, angular]


@pytest.mark.parametrize("kind", ["line", "arc"])
def test_timed_paths_are_consistent_and_at_rest_at_both_ends(kind, rng):
    start, end = random_pose(rng), random_pose(rng)
    if kind == "arc":
        centre = np.array([0.1, -0.2, 0.3])
        end[:3, 3] = centre + pin.exp3(np.array([0.3, 0.9, -0.4])) @ (start[:3, 3] - centre)
        path = ArcPath(start, end, centre)
    else:
        path = LinePath(start, end)
    timed = TimedPath(path, 3.0)
    np.testing.assert_allclose(timed(0.0)[0], start, atol=1e-12)
    np.testing.assert_allclose(timed(3.0)[0], end, atol=1e-12)
    for t in (0.0, 3.0, 4.0):
        _, twist, acceleration = timed.state(t)
        np.testing.assert_allclose(twist, 0.0, atol=1e-12)
        np.testing.assert_allclose(acceleration, 0.0, atol=1e-12)
    h = 1e-6
    for t in np.linspace(0.05, 2.95, 13):
        _, twist, acceleration = timed.state(t)
        np.testing.assert_allclose(finite_difference_twist(timed, t), twist, atol=1e-6)
        np.testing.assert_allclose((timed.state(t + h)[1] - timed.state(t - h)[1]) / (2 * h), acceleration, atol=1e-5)


def test_line_orientation_is_the_geodesic(rng):
    start, end = random_pose(rng), random_pose(rng)
    timed = TimedPath(LinePath(start, end), 2.0)
    axis = start[:3, :3] @ pin.log3(start[:3, :3].T @ end[:3, :3])
    angle = np.linalg.norm(axis)
    times = np.linspace(0.0, 2.0, 2001)
    omegas = np.array([timed(t)[1][3:] for t in times])
    moving = np.linalg.norm(omegas, axis=1) > 1e-9
    directions = omegas[moving] / np.linalg.norm(omegas[moving], axis=1)[:, None]
    np.testing.assert_allclose(directions, np.tile(axis / angle, (moving.sum(), 1)), atol=1e-12)  # fixed axis
    speed = np.linalg.norm(omegas, axis=1)
    travelled = np.sum(0.5 * (speed[1:] + speed[:-1]) * np.diff(times))
    assert travelled == pytest.approx(angle, rel=1e-6)  # no longer than the geodesic distance
    assert angle <= np.pi


def test_arc_positions_follow_eq2(rng):
    centre = np.array([0.4, 0.0, 0.5])
    start, end = np.eye(4), np.eye(4)
    start[:3, 3], end[:3, 3] = centre + [0.2, 0.0, 0.0], centre + [0.0, 0.2 * np.cos(0.3), 0.2 * np.sin(0.3)]
    path = ArcPath(start, end, centre)
    u0, u1, theta = start[:3, 3] - centre, end[:3, 3] - centre, np.pi / 2
    for s in np.linspace(0.0, 1.0, 11):
        paper = centre + (np.sin((1 - s) * theta) * u0 + np.sin(s * theta) * u1) / np.sin(theta)
        np.testing.assert_allclose(path.pose(s)[:3, 3], paper, atol=1e-12)
    assert path.length == pytest.approx(0.2 * np.pi / 2)


def test_sub_path_is_the_part_of_its_path(rng):
    path = LinePath(random_pose(rng), random_pose(rng))
    part = SubPath(path, 0.25, 0.75)
    np.testing.assert_allclose(part.pose(0.5), path.pose(0.5), atol=1e-12)
    np.testing.assert_allclose(part.derivatives(0.3)[0], 0.5 * path.derivatives(0.4)[0], atol=1e-12)
    with pytest.raises(InvalidInputError):
        SubPath(path, 0.5, 0.5)


def test_paths_reject_bad_input():
    pose = np.eye(4)
    other = np.eye(4)
    other[:3, 3] = [1.0, 0.0, 0.0]
    with pytest.raises(InvalidInputError):
        LinePath(pose, pose)
    with pytest.raises(InvalidInputError):
        ArcPath(pose, other, [0.0, 0.5, 0.0])  # unequal radii
    with pytest.raises(InvalidInputError):
        ArcPath(pose, other, [0.5, 0.0, 0.0])  # diametrically opposite: no plane
    with pytest.raises(InvalidInputError):
        TimedPath(LinePath(pose, other), 0.0)


# ------------------------------------------------------------------------------- IK
def test_ik_seeded_nearby_returns_the_seeds_branch(puma, rng):
    tested = 0
    while tested < 20:
        q = puma.random_configuration(rng)
        if singularity_measure(puma, q) < 1e-3:  # near a singular set IK solutions merge
            continue
        tested += 1
        result = solve_ik(puma, "ee", puma.frame_pose(q, "ee"), q + rng.normal(scale=0.02, size=6))
        assert result.converged and result.position_error < 1e-10
        np.testing.assert_allclose(result.q, q, atol=1e-8)


def test_ik_reports_unreachable_poses(puma):
    far = np.eye(4)
    far[:3, 3] = [3.0, 0.0, 0.0]
    result = solve_ik(puma, "ee", far, np.zeros(6), max_iterations=50)
    assert not result.converged and result.position_error > 1.0


# ------------------------------------------------------------------------------- flips
def synthetic(puma, swing_time):
    """Joints 4 and 6 counter-rotate by 2.6 rad (tanh profile of width swing_time) at t = 5 s;
    theta5 changes sign at t = 2 s."""
    t = np.linspace(0.0, 10.0, 4001)
    q = np.zeros((t.size, 6))
    q[:, 3] = 1.3 * np.tanh((t - 5.0) / swing_time)
    q[:, 5] = -q[:, 3]
    q[:, 4] = 0.2 * np.tanh(t - 2.0)
    return JointTrajectory(t, q, np.gradient(q, t, axis=0), np.ones(t.size), np.zeros(0))


def test_fast_counter_rotation_is_a_flip_slow_is_not(puma):
    fast = wrist_flips(puma, synthetic(puma, 0.05), ("joint_4", "joint_6"))
    assert len(fast) == 1
    assert 4.9 < fast[0].start < fast[0].end < 5.1
    assert fast[0].change_a >= np.pi / 2 and fast[0].change_b <= -np.pi / 2
    assert wrist_flips(puma, synthetic(puma, 3.0), ("joint_4", "joint_6")) == []  # ~0.43 rad/s at most
    same_direction = synthetic(puma, 0.05)
    same_direction.q[:, 5] *= -1.0
    assert wrist_flips(puma, same_direction, ("joint_4", "joint_6")) == []
    with pytest.raises(InvalidInputError):
        wrist_flips(puma, same_direction, ("joint_4", "joint_9"))


def test_branch_switch_is_a_sign_change_of_theta5(puma):
    switches = branch_switches(puma, synthetic(puma, 0.05), "joint_5")
    assert switches.size == 1 and switches[0] == pytest.approx(2.0, abs=0.01)
    assert branch_switches(puma, synthetic(puma, 0.05), "joint_4").size == 1  # theta4 crosses 0 at t = 5
