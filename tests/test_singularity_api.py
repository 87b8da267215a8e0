"""wbc.analysis.singularity against independent rank computations: property tests on random configurations
within the limits and on / epsilon-near every singular set, lost directions (Kapustina eq. 7), the
singular-region measure, the Scorbot angle conversion and input errors."""

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import wbc
from dh_tables import PUMA, SCORBOT
from test_youbot_model import A1, A2, A3, C
from wbc.analysis import singularity as sing

MODELS = ["youbot", "scorbot_er4pc", "puma560"]


@pytest.fixture(scope="module")
def robots():
    return {name: wbc.load_robot(name) for name in MODELS}


def svd_rank(J, tol=1e-10):
    sigma = np.linalg.svd(J, compute_uv=False)
    return int(np.sum(sigma > tol * sigma[0]))


def raw_rank(robot, q, columns=None):
    J = robot.frame_jacobian(q, "ee")
    return svd_rank(J if columns is None else J[:, columns])


# Singular sets written out here from the derivations (tests/test_singularity_derivations.py), not from wbc.
def youbot_singular(q):
    return (abs(np.sin(q[4])) < 1e-9 and abs(np.sin(q[4] + q[5])) < 1e-9) or abs(np.sin(q[4] + q[5] + q[6])) < 1e-9


def youbot_arm_singular(q):
    t234 = q[4] + q[5] + q[6]
    ell = A1 + A2 * np.sin(q[4]) + A3 * np.sin(q[4] + q[5]) + C * np.sin(t234)
    return abs(np.sin(q[5])) < 1e-9 or (abs(np.sin(t234)) < 1e-9 and abs(ell) < 1e-9)


def scorbot_singular(q):
    g = SCORBOT
    q2, q3, q4 = q[1], q[1] + q[2], q[1] + q[2] + q[3]
    radius = g["l1"] + g["l2"] * np.cos(q2) + g["l3"] * np.cos(q3) + g["d5"] * np.cos(q4)
    return abs(np.sin(q3 - q2)) < 1e-9 or (abs(np.cos(q4)) < 1e-9 and abs(radius) < 1e-9)


def puma_singular(q):
    g = PUMA
    elbow = g["a3"] * np.sin(q[2]) + g["d4"] * np.cos(q[2])
    shoulder = g["a2"] * np.cos(q[1]) + g["a3"] * np.cos(q[1] + q[2]) - g["d4"] * np.sin(q[1] + q[2])
    return abs(np.sin(q[4])) < 1e-9 or abs(elbow) < 1e-9 or abs(shoulder) < 1e-9


CASES = [("youbot", None, youbot_singular, None, 6), ("youbot", "arm", youbot_arm_singular, slice(3, 8), 5),
         ("scorbot_er4pc", None, scorbot_singular, None, 5), ("puma560", None, puma_singular, None, 6)]


@pytest.mark.parametrize("name, subsystem, derived, columns, full", CASES)
def test_thousands_of_random_configurations_agree(robots, rng, name, subsystem, derived, columns, full):
    robot = robots[name]
    for _ in range(2000):
        q = robot.random_configuration(rng)
        singular = raw_rank(robot, q, columns) < full
        assert singular == derived(q) == sing.is_singular(robot, q, subsystem=subsystem)
        assert sing.numeric_rank(robot, q, subsystem=subsystem) == raw_rank(robot, q, columns)


@pytest.mark.parametrize("name, subsystem, derived, columns, full", CASES)
def test_on_and_epsilon_near_every_set(robots, rng, name, subsystem, derived, columns, full):
    """Configurations on each set (found by the conditions' projections, then checked against the derived
    condition written here) are rank-deficient; moved 1e-3 off the set they are full rank."""
    robot = robots[name]
    for condition in sing.analytic_conditions(robot, subsystem):
        found = 0
        for _ in range(2000):
            q = condition.project(robot.random_configuration(rng))
            if q is None:
                continue
            found += 1
            assert robot.within_limits(q)
            assert derived(q), condition.name
            assert raw_rank(robot, q, columns) == condition.rank < full
            assert sing.is_singular(robot, q, subsystem=subsystem)
            step = rng.normal(size=q.size)
            near = np.clip(q + 1e-3 * step / np.linalg.norm(step), robot.lower, robot.upper)
            if condition.residual(near) > 1e-4:
                assert raw_rank(robot, near, columns) == full
                assert not derived(near) and not sing.is_singular(robot, near, subsystem=subsystem)
            if found == 200:
                break
        assert found == 200, condition.name


def puma_factors(q):
    g = PUMA
    return np.array([np.sin(q[4]), g["a3"] * np.sin(q[2]) + g["d4"] * np.cos(q[2]),
                     g["a2"] * np.cos(q[1]) + g["a3"] * np.cos(q[1] + q[2]) - g["d4"] * np.sin(q[1] + q[2])])


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6), st.sampled_from([0, 1, 2]),
       st.floats(1e-5, 1e-3), st.sampled_from([-1.0, 1.0]))
def test_puma_on_and_near_each_factor(robots, unit, factor, epsilon, sign):
    """hypothesis: any PUMA configuration put on one factor's zero set (by hand), then nudged off it."""
    robot = robots["puma560"]
    q = robot.lower + np.array(unit) * (robot.upper - robot.lower)
    g = PUMA
    if factor == 0:
        q[4] = 0.0
    elif factor == 1:
        q[2] = np.arctan2(-g["d4"], g["a3"])
    else:
        big_a = g["a2"] + g["a3"] * np.cos(q[2]) - g["d4"] * np.sin(q[2])
        big_b = g["a3"] * np.sin(q[2]) + g["d4"] * np.cos(q[2])
        q[1] = np.pi / 2 - np.arctan2(big_b, big_a)
    assert abs(puma_factors(q)[factor]) < 1e-12
    assert sing.is_singular(robot, q) and raw_rank(robot, q) < 6
    q[(4, 2, 1)[factor]] += sign * epsilon
    if np.all(np.abs(np.delete(puma_factors(q), factor)) > 1e-2):
        assert not sing.is_singular(robot, q) and raw_rank(robot, q) == 6


# --------------------------------------------------------------------- lost directions
def _arm_axes(q):
    phi1 = q[2] + q[3]
    radial = np.array([np.cos(phi1), np.sin(phi1), 0.0])
    normal = np.array([-np.sin(phi1), np.cos(phi1), 0.0])  # axis of joints 2-4 (Kapustina's C1Y1)
    return radial, normal


def _producible(J, twist):
    v = np.linalg.lstsq(J, twist, rcond=None)[0]
    return np.linalg.norm(J @ v - twist) < 1e-9


@pytest.mark.parametrize("theta4", [0.6, -1.2, 1.5])
def test_eq7_lost_motion_with_theta4_nonzero(robots, theta4):
    """theta2 = theta3 = 0, theta4 != 0: one lost direction, w = (e_z; c sin(theta4) y1) normalised:
    Z_E' + c sin(theta4) theta_E' = 0 -- neither pure vertical translation nor pure rotation about y1 through E."""
    robot = robots["youbot"]
    q = np.array([0.3, -0.4, 0.5, 0.7, 0.0, 0.0, theta4, 0.4])
    W = sing.lost_directions(robot, q)
    assert W.shape == (6, 1)
    _, normal = _arm_axes(q)
    expected = np.r_[0.0, 0.0, 1.0, C * np.sin(theta4) * normal]
    expected /= np.linalg.norm(expected)
    assert abs(W[:, 0] @ expected) == pytest.approx(1.0, abs=1e-12)
    J = robot.frame_jacobian(q, "ee")
    assert not _producible(J, np.r_[0, 0, 1.0, 0, 0, 0])
    assert not _producible(J, np.r_[0, 0, 0, normal])
    assert _producible(J, np.r_[0, 0, -C * np.sin(theta4), normal])  # the coupled motion of eq. 7


def test_eq7_lost_motion_with_theta4_zero_and_the_extra_one(robots):
    """theta2 = theta3 = theta4 = 0: E cannot move vertically (eq. 7) -- and, the gripper being vertical,
    nothing turns it about the radial axis x1 either: two lost directions, rank 4."""
    robot = robots["youbot"]
    q = np.array([0.3, -0.4, 0.5, 0.7, 0.0, 0.0, 0.0, 0.4])
    W = sing.lost_directions(robot, q)
    assert W.shape == (6, 2)
    radial, _ = _arm_axes(q)
    basis = np.c_[np.r_[0, 0, 1.0, 0, 0, 0], np.r_[0, 0, 0, radial]]
    np.testing.assert_allclose(W @ W.T, basis @ basis.T, atol=1e-12)  # same subspace


@pytest.mark.parametrize("name", MODELS)
def test_lost_directions_are_an_orthonormal_left_null_space(robots, rng, name):
    robot = robots[name]
    for _ in range(50):
        q = robot.random_configuration(rng)
        W = sing.lost_directions(robot, q)
        J = robot.frame_jacobian(q, "ee")
        assert W.shape == (6, 6 - svd_rank(J))
        np.testing.assert_allclose(W.T @ W, np.eye(W.shape[1]), atol=1e-12)
        np.testing.assert_allclose(W.T @ J, 0.0, atol=1e-9)
    if name == "scorbot_er4pc":  # a 5-DOF arm always lacks one direction
        assert W.shape == (6, 1)


# ---------------------------------------------------------------------- singular region
def _scaled(J, length):
    D = np.r_[np.full(3, 1.0 / length), np.ones(3)]
    Js = D[:, None] * J
    translational = np.all(J[3:] == 0.0, axis=0)
    Js[:, translational] *= length
    return Js


def test_measure_is_det_of_the_scaled_gram_matrix(robots, rng):
    puma, scorbot, youbot = robots["puma560"], robots["scorbot_er4pc"], robots["youbot"]
    for _ in range(20):
        q = puma.random_configuration(rng)
        Js = _scaled(puma.frame_jacobian(q, "ee"), 0.4318 + 0.4318)
        assert sing.singularity_measure(puma, q) == pytest.approx(np.linalg.det(Js) ** 2, rel=1e-9)
        q = scorbot.random_configuration(rng)
        Js = _scaled(scorbot.frame_jacobian(q, "ee"), 0.22 + 0.22 + 0.145)
        assert sing.singularity_measure(scorbot, q) == pytest.approx(np.linalg.det(Js.T @ Js), rel=1e-9)
        q = youbot.random_configuration(rng)
        Js = _scaled(youbot.frame_jacobian(q, "ee"), A2 + A3 + C)
        assert sing.singularity_measure(youbot, q) == pytest.approx(np.linalg.det(Js @ Js.T), rel=1e-9)


def test_measure_does_not_depend_on_the_length_unit(robots, tmp_path, rng):
    """The PUMA rebuilt in millimetres: det(J^T J) grows by 1000^6, the scaled measure does not move."""
    text = wbc.model_path("puma560").read_text()
    def scale(m):
        return 'xyz="' + " ".join(repr(1000.0 * float(v)) for v in m.group(1).split()) + '"'

    text = re.sub(r'xyz="([^"]*)"', scale, text).replace('name="puma560"', 'name="puma560_mm"')
    path = tmp_path / "puma560_mm.urdf"
    path.write_text(text)
    metres, millimetres = robots["puma560"], wbc.load_robot(path)
    for _ in range(20):
        q = metres.random_configuration(rng)
        Jm, Jmm = metres.frame_jacobian(q, "ee"), millimetres.frame_jacobian(q, "ee")
        assert np.linalg.det(Jmm.T @ Jmm) == pytest.approx(1e18 * np.linalg.det(Jm.T @ Jm), rel=1e-6)
        assert sing.singularity_measure(millimetres, q, "ee", length_scale=1000 * (0.4318 + 0.4318)) == pytest.approx(
            sing.singularity_measure(metres, q), rel=1e-9)


def test_singular_region_contains_the_set_and_shrinks_with_the_threshold(robots):
    puma = robots["puma560"]
    q = np.array([0.3, 0.6, -0.8, 0.4, 0.0, 0.2])
    assert sing.in_singular_region(puma, q, 1e-12)
    q[4] = 0.3
    reference = sing.singularity_measure(puma, q)
    q[4] = 0.03
    drop = (np.sin(0.03) / np.sin(0.3)) ** 2  # det J is proportional to sin(theta5): the measure to its square
    assert sing.singularity_measure(puma, q) == pytest.approx(reference * drop, rel=1e-9)
    assert sing.in_singular_region(puma, q, reference * drop * 1.01)
    assert not sing.in_singular_region(puma, q, reference * drop * 0.99)


# --------------------------------------------------------------------- Scorbot angles
def test_scorbot_measured_angles_are_eq14():
    theta = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    np.testing.assert_allclose(sing.scorbot_measured_angles(theta), [0.1, 0.2, 0.5, 0.9, 0.5], atol=1e-15)
    np.testing.assert_allclose(sing.scorbot_dh_angles([0.1, 0.2, 0.5, 0.9, 0.5]), theta, atol=1e-15)


# ------------------------------------------------------------------------- errors, API
def test_conditions_are_readable(robots):
    for name in MODELS:
        for condition in sing.analytic_conditions(robots[name]):
            assert condition.name and "=" in condition.formula
    assert [s.name for s in sing.singular_systems(robots["youbot"])] == ["whole_body", "arm"]
    assert [c.rank for c in sing.analytic_conditions(robots["youbot"], "arm")] == [4, 4]


def test_unknown_model_and_bad_input_raise_clear_errors(robots, tmp_path):
    text = wbc.model_path("puma560").read_text().replace('name="puma560"', 'name="mystery"')
    path = tmp_path / "mystery.urdf"
    path.write_text(text)
    mystery = wbc.load_robot(path)
    with pytest.raises(wbc.ModelError, match="no certified singular conditions"):
        sing.analytic_conditions(mystery)
    with pytest.raises(wbc.ModelError):
        sing.is_singular(mystery, np.zeros(6))
    generic = np.array([0.3, 0.6, -0.8, 0.4, 0.9, 0.2])
    assert sing.numeric_rank(mystery, generic, frame="ee") == 6  # numeric tools work on any robot
    assert sing.numeric_rank(mystery, np.zeros(6), frame="ee") == 5  # theta5 = 0
    with pytest.raises(wbc.InvalidInputError, match="length_scale"):
        sing.in_singular_region(mystery, np.zeros(6), 1e-3, frame="ee")
    assert not sing.in_singular_region(mystery, generic, 1e-6, frame="ee",
                                       length_scale=0.8636)
    youbot = robots["youbot"]
    with pytest.raises(wbc.InvalidInputError, match="shape"):
        sing.is_singular(youbot, np.zeros(5))
    with pytest.raises(wbc.InvalidInputError, match="NaN"):
        sing.numeric_rank(youbot, np.full(8, np.nan))
    with pytest.raises(wbc.InvalidInputError, match="subsystem"):
        sing.analytic_conditions(youbot, "legs")
    with pytest.raises(wbc.InvalidInputError, match="threshold"):
        sing.in_singular_region(youbot, np.zeros(8), -1.0)
    with pytest.raises(wbc.InvalidInputError, match="tol"):
        sing.is_singular(youbot, np.zeros(8), tol=0.0)
    with pytest.raises(wbc.UnknownFrameError):
        sing.numeric_rank(youbot, np.zeros(8), frame="nose")
    with pytest.raises(wbc.InvalidInputError, match="shape"):
        sing.scorbot_dh_angles([1.0, 2.0])
