"""De Luca's mobile manipulator: its singular set derived symbolically from the model's own
joint structure (sympy) and checked against the rank of the shipped Pinocchio model."""

import itertools

import numpy as np
import pytest
import sympy as sp

import wbc
from wbc.analysis.singularity import is_singular, lost_directions, numeric_rank, verify

X, Y, TH, T1, T2, T3 = sp.symbols("x y theta theta1 theta2 theta3", real=True)
D0, L2, L3 = sp.symbols("d0 l2 l3", positive=True)
VALUES = {D0: 0.6, L2: 0.432, L3: 0.432}


def rot_z(a):
    return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])


def rot_minus_y(a):
    """Rotation by a about -y (the axis of joints 2 and 3 in the URDF)."""
    return sp.Matrix([[sp.cos(a), 0, -sp.sin(a)], [0, 1, 0], [sp.sin(a), 0, sp.cos(a)]])


@pytest.fixture(scope="module")
def symbolic():
    """Wrist centre from the URDF's chain: base (x, y) -> joint 1 (z) -> joint 2 at d0 (-y)
    -> joint 3 at l2 along x (-y) -> wrist at l3 along x; the steering joint is a side branch."""
    r1 = rot_z(T1)
    r2 = r1 * rot_minus_y(T2)
    r3 = r2 * rot_minus_y(T3)
    p = sp.Matrix([X, Y, 0]) + sp.Matrix([0, 0, D0]) + r2 * sp.Matrix([L2, 0, 0]) + r3 * sp.Matrix([L3, 0, 0])
    J = p.jacobian([X, Y, TH, T1, T2, T3])
    S = sp.zeros(6, 5)
    S[0, 0], S[1, 0], S[2, 1], S[3, 2], S[4, 3], S[5, 4] = sp.cos(TH), sp.sin(TH), 1, 1, 1, 1
    return p, sp.simplify(J * S)


def test_symbolic_chain_is_the_shipped_model(symbolic, rng):
    p, J_u = symbolic
    robot = wbc.load_robot("deluca_mm")
    position = sp.lambdify((X, Y, TH, T1, T2, T3), p.subs(VALUES))
    jacobian = sp.lambdify((X, Y, TH, T1, T2, T3), J_u.subs(VALUES))
    for _ in range(100):
        q = robot.random_configuration(rng, base_range=3.0)
        np.testing.assert_allclose(np.ravel(position(*q)), robot.frame_pose(q, "wrist_center")[:3, 3], atol=1e-12)
        np.testing.assert_allclose(jacobian(*q), robot.frame_jacobian(q, "wrist_center")[:3] @ robot.input_map(q),
                                   atol=1e-12)


def test_minors_factor_into_the_three_conditions(symbolic):
    """J_u's omega column is zero; its four 3x3 minors over (v, th1, th2, th3) are, with the
    reach R = l2 c2 + l3 c23:  R^2 c(th-th1), l3 R c23 c(th-th1), -l2 l3 s3 s(th-th1), -l2 l3 R s3.
    All vanish iff (R = 0 and s(th - th1) = 0) or (s3 = 0 and c(th - th1) = 0) or (R = 0 and s3 = 0):
    from the last minor R = 0 or s3 = 0; R = 0 leaves only -l2 l3 s3 s(th-th1); s3 = 0 with R != 0
    leaves R^2 c(th-th1)."""
    _, J_u = symbolic
    assert J_u[:, 1] == sp.zeros(3, 1)
    reach = L2 * sp.cos(T2) + L3 * sp.cos(T2 + T3)
    expected = {
        (0, 2, 3): reach**2 * sp.cos(TH - T1),
        (0, 2, 4): L3 * reach * sp.cos(T2 + T3) * sp.cos(TH - T1),
        (0, 3, 4): -L2 * L3 * sp.sin(T3) * sp.sin(TH - T1),
        (2, 3, 4): -L2 * L3 * reach * sp.sin(T3),
    }
    for columns in itertools.combinations((0, 2, 3, 4), 3):
        minor = J_u[:, list(columns)].det()
        assert sp.simplify(sp.expand_trig(minor - expected[columns])) == 0, columns


def test_documents_arm_conditions_and_base_recovery(symbolic):
    """The arm alone (columns th1..th3) has det = -l2 l3 s3 R: De Luca's two arm singularities;
    the base recovers the first unless th = th1 + k pi, the second unless th = th1 +- pi/2."""
    _, J_u = symbolic
    reach = L2 * sp.cos(T2) + L3 * sp.cos(T2 + T3)
    assert sp.simplify(sp.expand_trig(J_u[:, 2:].det() + L2 * L3 * sp.sin(T3) * reach)) == 0


def test_rank_agrees_with_the_conditions_on_and_off_the_sets(rng):
    robot = wbc.load_robot("deluca_mm")
    for subsystem in ("whole_body", "arm"):
        for report in verify(robot, rng, samples=2000, on_set=100, subsystem=subsystem):
            assert report.agree == report.total > 0, (subsystem, report.label)


def test_examples_from_the_document():
    robot = wbc.load_robot("deluca_mm")
    # wrist centre on axis 1 (theta2 = 90 deg, theta3 = 0 is also stretched: take theta3 = -60 deg)
    t3 = -np.pi / 3
    t2 = np.arctan2(0.432 + 0.432 * np.cos(t3), 0.432 * np.sin(t3))  # l2 c2 + l3 c23 = 0
    on_axis = np.array([0.0, 0.0, 0.4, 0.4, t2, t3])  # wheels parallel to the arm plane
    assert numeric_rank(robot, on_axis) == 2 and is_singular(robot, on_axis)
    lost = lost_directions(robot, on_axis)
    np.testing.assert_allclose(np.abs(lost[:, 0]), np.abs([-np.sin(0.4), np.cos(0.4), 0.0]), atol=1e-9)
    turned = on_axis.copy()
    turned[2] = 0.4 + 0.3  # the wheels turned away from the arm plane recover the lost direction
    assert numeric_rank(robot, turned) == 3 and not is_singular(robot, turned)
    stretched = np.array([0.0, 0.0, 0.4 + np.pi / 2, 0.4, 0.3, 0.0])  # wheels normal to the links
    assert numeric_rank(robot, stretched) == 2 and is_singular(robot, stretched)
    double = np.array([0.0, 0.0, 1.0, 0.4, np.pi / 2, 0.0])  # both: no steering helps
    assert numeric_rank(robot, double) == 2 and is_singular(robot, double)
