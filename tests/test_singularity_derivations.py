"""Symbolic derivations (sympy) of every certified singular set, from each model's own geometry,
each checked numerically against the rank of the shipped Pinocchio Jacobian.

A 6 x n Jacobian (n >= 6) loses rank exactly where all its 6 x 6 minors vanish together; a
6 x n one with n < 6 loses column rank where all n x n minors vanish. Rank is unchanged by
invertible changes of the task frame (rotating the rows, moving the reference point along the
same body) and of the joint coordinates, which the derivations use to simplify the algebra.
"""

import itertools

import numpy as np
import pytest
import sympy as sp

import wbc
from conftest import random_youbot_configurations
from dh_tables import PUMA, SCORBOT, dh_frames, puma_table, scorbot_table, symbolic_geometric_jacobian, trig_to_symbols
from test_youbot_model import A1, A2, A3, D1, C, H

pi = sp.pi


def rank(J, tol=1e-10):
    sigma = np.linalg.svd(J, compute_uv=False)
    return int(np.sum(sigma > tol * sigma[0]))


def rot_z(a):
    return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])


def rot_x(a):
    return sp.Matrix([[1, 0, 0], [0, sp.cos(a), -sp.sin(a)], [0, sp.sin(a), sp.cos(a)]])


def maximal_minors(J):
    """All maximal minors of J: over column subsets if J is wide, row subsets if tall."""
    rows, cols = J.shape
    if cols >= rows:
        return {s: J[:, list(s)].det() for s in itertools.combinations(range(cols), rows)}
    return {s: J[list(s), :].det() for s in itertools.combinations(range(rows), cols)}


# =========================================================================== youBot
Q = sp.symbols("X_C Y_C theta theta1:6", real=True)
X_C, Y_C, TH, T1, T2, T3, T4, T5 = Q
h, a1, d1, a2, a3, c = sp.symbols("h a1 d1 a2 a3 c", positive=True)
YOUBOT_VALUES = {h: H, a1: A1, d1: D1, a2: A2, a3: A3, c: C}
# absolute angles: phi1 = theta + theta1 (arm plane), phi2 = theta2, phi3 = theta2 + theta3, phi4 = theta_E
PHI = sp.symbols("phi1:5", real=True)
TO_ABSOLUTE = {T1: PHI[0] - TH, T2: PHI[1], T3: PHI[2] - PHI[1], T4: PHI[3] - PHI[2]}


@pytest.fixture(scope="module")
def kapustina():
    """Eq. (2): X = (X_E, Y_E, Z_E, psi, theta_E, phi), her Jacobian dX/dQ and the Euler-rate map E."""
    ell = a1 + a2 * sp.sin(T2) + a3 * sp.sin(T2 + T3) + c * sp.sin(T2 + T3 + T4)
    position = sp.Matrix([X_C + h * sp.cos(TH) + sp.cos(TH + T1) * ell,
                          Y_C + h * sp.sin(TH) + sp.sin(TH + T1) * ell,
                          d1 + a2 * sp.cos(T2) + a3 * sp.cos(T2 + T3) + c * sp.cos(T2 + T3 + T4)])
    psi, theta_e, phi = TH + T1 + pi / 2, T2 + T3 + T4, T5 + pi / 2
    euler_jacobian = sp.Matrix.vstack(position, sp.Matrix([psi, theta_e, phi])).jacobian(Q)
    # R = Rz(psi) Rx(theta_E) Rz(phi)  =>  omega = psi' e_z + theta_E' Rz(psi) e_x + phi' Rz(psi) Rx(theta_E) e_z
    rate_map = sp.Matrix.hstack(sp.Matrix([0, 0, 1]), rot_z(psi)[:, 0], (rot_z(psi) * rot_x(theta_e))[:, 2])
    return euler_jacobian, rate_map, psi, theta_e


def as_polynomials(J):
    """J in absolute angles with sin/cos replaced by symbols (s_i, c_i) of (theta, phi1..phi4)."""
    return trig_to_symbols(J.subs(TO_ABSOLUTE), (TH,) + PHI)


def test_geometric_jacobian_is_rate_map_times_euler_jacobian(youbot, kapustina, rng):
    """J_geo = diag(I, E) J_euler, checked against Pinocchio: this certifies the symbolic model."""
    euler_jacobian, rate_map, _, _ = kapustina
    geometric = sp.lambdify(Q, sp.diag(sp.eye(3), rate_map).subs(YOUBOT_VALUES) * euler_jacobian.subs(YOUBOT_VALUES))
    for q in random_youbot_configurations(rng, 100):
        np.testing.assert_allclose(np.array(geometric(*q), dtype=float), youbot.frame_jacobian(q, "ee"),
                                   rtol=0, atol=1e-12)


def test_euler_rate_map_is_singular_exactly_at_theta_e_0_or_pi(kapustina):
    _, rate_map, _, theta_e = kapustina
    assert sp.simplify(rate_map.det() + sp.sin(theta_e)) == 0


@pytest.mark.slow  # sympy derivation
def test_euler_jacobian_minors_give_kapustinas_set_theta2_theta3_zero(kapustina):
    """Her J (rows X_E, Y_E, Z_E, psi, theta_E, phi) has rank < 6 iff sin(theta2) = sin(theta2 + theta3) = 0."""
    euler_jacobian, _, _, _ = kapustina
    poly, s, co = as_polynomials(euler_jacobian)
    minors = {k: sp.factor(m) for k, m in maximal_minors(poly).items()}
    s2, s23 = s[2], s[3]  # sin(theta2), sin(theta2 + theta3)
    sin_theta3 = s[3] * co[2] - co[3] * s[2]
    # columns (X_C, Y_C, theta1 or theta, two of theta2..4, theta5): a2 s2, a2 s2 + a3 s23, a3 s23
    for first in (2, 3):
        assert minors[(0, 1, first, 4, 5, 7)] == a2 * s2
        assert sp.expand(minors[(0, 1, first, 4, 6, 7)] - (a2 * s2 + a3 * s23)) == 0
        assert minors[(0, 1, first, 5, 6, 7)] == a3 * s23
    # every other minor is a multiple of one of these or of a2 a3 sin(theta3) = a2 a3 (s23 c2 - c23 s2)
    for m in minors.values():
        assert any(sp.cancel(m / f).is_polynomial(*s, *co) for f in (a2 * s2, a3 * s23, a2 * s2 + a3 * s23,
                                                                     a2 * a3 * sin_theta3)) or m == 0
    # so all vanish together iff sin(theta2) = sin(theta2 + theta3) = 0; within eq. (1)
    # (theta2 in [-65, 90] deg, theta3 in [-151, 146] deg) that is theta2 = theta3 = 0
    deg = np.pi / 180
    assert [k for k in range(-3, 4) if -65 * deg <= k * np.pi <= 90 * deg] == [0]
    assert [k for k in range(-3, 4) if -151 * deg <= k * np.pi <= 146 * deg] == [0]


def test_geometric_jacobian_also_loses_rank_with_the_gripper_vertical(youbot, kapustina):
    """Every 6 x 6 minor of J_geo = diag(I, E) J_euler is det(E) = -sin(theta_E) times the Euler one, so J_geo is
    singular on {theta2 = theta3 = 0} and on {sin(theta2 + theta3 + theta4) = 0}. The mechanism's orientation
    chain is itself a ZXZ gimbal (vertical yaw axes, horizontal pitch axes, the roll axis of the gripper), so the
    Euler chart's singularity is a true one: with the gripper vertical no joint turns E about the radial axis."""
    euler_jacobian, rate_map, _, _ = kapustina
    euler = sp.lambdify(Q, euler_jacobian.subs(YOUBOT_VALUES))
    up = np.array([0.4, -0.2, 0.3, 0.5, 0.4, 0.7, -1.1, 0.9])  # theta_E = 0 with theta2, theta3 != 0
    down = np.array([0.4, -0.2, 0.3, 0.5, 0.6, 1.2, np.pi - 1.8, 0.9])  # theta_E = pi
    for q in (up, down):
        assert youbot.within_limits(q)
        assert rank(np.array(euler(*q), dtype=float)) == 6  # Kapustina's J: full rank ...
        assert rank(youbot.frame_jacobian(q, "ee")) == 5  # ... the mechanism: not
    both = np.array([0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 0.2])  # stretched straight up: both sets meet
    assert rank(youbot.frame_jacobian(both, "ee")) == 4
    assert rank(np.array(euler(*both), dtype=float)) == 5


def test_eq7_lost_motions_follow_from_the_left_null_space(kapustina):
    """At theta2 = theta3 = 0 her J has the left null vector (Z_E: 1, theta_E: c sin(theta4)): Z_E' = -c sin(theta4)
    theta_E' (eq. 7 with b = +1). With theta4 = 0 this is Z_E' = 0."""
    euler_jacobian, _, _, _ = kapustina
    at_set = euler_jacobian.subs({T2: 0, T3: 0})
    null = at_set.T.nullspace()
    assert len(null) == 1
    w = sp.simplify(null[0] / null[0][2])
    assert list(w) == [0, 0, 1, 0, c * sp.sin(T4), 0]


def _arm_frame(J, phi1):
    """Rows rotated into the arm plane frame (x1 radial, y1 normal, z up): rank unchanged."""
    turn = rot_z(phi1).T
    return sp.diag(turn, turn) * J


@pytest.mark.slow  # sympy derivation
def test_youbot_arm_alone_set(youbot, kapustina):
    """Base fixed (columns theta1..theta5, 6 x 5): the six 5 x 5 minors are a2 a3 sin(theta3) times
    (ell sin(theta_E), ell cos(theta_E), sin(theta_E)) up to sign, ell = horizontal distance of E from axis 1.
    Common zeros: sin(theta3) = 0, or ell = 0 and sin(theta_E) = 0 (gripper vertical on axis 1)."""
    euler_jacobian, rate_map, _, _ = kapustina
    arm = _arm_frame(sp.diag(sp.eye(3), rate_map) * euler_jacobian[:, 3:], TH + T1)
    poly, s, co = as_polynomials(sp.simplify(arm))
    minors = [sp.factor(m) for m in maximal_minors(poly).values()]
    ell = a1 + a2 * s[2] + a3 * s[3] + c * s[4]
    sin_theta3 = s[3] * co[2] - co[3] * s[2]
    nonzero = [m for m in minors if m != 0]
    expected = [ell * s[4], ell * co[4], s[4]]
    assert len(nonzero) == len(expected)
    for e in expected:
        assert sum(sp.expand(m - sign * a2 * a3 * sin_theta3 * e) == 0 for m in nonzero for sign in (1, -1)) == 1
    # numerically, on the second component (E on axis 1, gripper vertical) and just off it
    q = np.zeros(8)
    q[3:8] = [0.3, -30 * np.pi / 180, 0.0, 0.0, 0.5]
    q[5] = np.arcsin(-(A1 + A2 * np.sin(q[4])) / A3) - q[4]
    q[6] = -(q[4] + q[5])
    assert youbot.within_limits(q)
    assert abs(youbot.frame_pose(q, "ee")[0, 3] - H) < 1e-12  # E above axis 1 (x = h at zero base pose)
    assert rank(youbot.frame_jacobian(q, "ee")[:, 3:]) == 4
    q[6] += 1e-3
    assert rank(youbot.frame_jacobian(q, "ee")[:, 3:]) == 5
    # and the elbow: theta3 = 0 with everything else generic
    q = np.array([0, 0, 0, 0.3, 0.5, 0.0, 0.7, 0.2])
    assert rank(youbot.frame_jacobian(q, "ee")[:, 3:]) == 4


# ========================================================================== Scorbot
TH5 = sp.symbols("theta1:6", real=True)
QS = sp.symbols("q1:6", real=True)
d1s, l1s, l2s, l3s, d5s = sp.symbols("d1 l1 l2 l3 d5", positive=True)
SCORBOT_VALUES = {d1s: SCORBOT["d1"], l1s: SCORBOT["l1"], l2s: SCORBOT["l2"], l3s: SCORBOT["l3"], d5s: SCORBOT["d5"]}
# eq. (14): q = (theta1, theta2, theta2 + theta3, theta2 + theta3 + theta4, theta5); d theta / d q:
DTHETA_DQ = sp.Matrix([[1, 0, 0, 0, 0], [0, 1, 0, 0, 0], [0, -1, 1, 0, 0], [0, 0, -1, 1, 0], [0, 0, 0, 0, 1]])


def theta_from_q(q):
    return np.array([q[0], q[1], q[2] - q[1], q[3] - q[2], q[4]])


@pytest.fixture(scope="module")
def scorbot_jacobian_q():
    """Geometric Jacobian (world axes, at the tool point) from Table 1, in the measured angles q."""
    geometry = dict(d1=d1s, l1=l1s, l2=l2s, l3=l3s, d5=d5s)
    frames = dh_frames(scorbot_table(TH5, geometry, pi=pi), lib=sp)
    J = symbolic_geometric_jacobian(frames, frames[-1][:3, 3])
    to_q = {TH5[0]: QS[0], TH5[1]: QS[1], TH5[2]: QS[2] - QS[1], TH5[3]: QS[3] - QS[2], TH5[4]: QS[4]}
    return sp.simplify(J.subs(to_q) * DTHETA_DQ)


def gierlak_eq15():
    s = [sp.sin(v) for v in QS]
    co = [sp.cos(v) for v in QS]
    R = l1s + l2s * co[1] + l3s * co[2] + d5s * co[3]
    return sp.Matrix([
        [-R * s[0], -l2s * s[1] * co[0], -l3s * s[2] * co[0], -d5s * s[3] * co[0], 0],
        [R * co[0], -l2s * s[1] * s[0], -l3s * s[2] * s[0], -d5s * s[3] * s[0], 0],
        [0, l2s * co[1], l3s * co[2], d5s * co[3], 0],
        [0, 0, 0, s[0], co[3] * co[0]],
        [0, 0, 0, -co[0], co[3] * s[0]],
        [1, 0, 0, 0, s[3]]])


@pytest.mark.slow  # sympy derivation
def test_scorbot_jacobian_is_gierlaks_eq15_and_pinocchios(scorbot_jacobian_q, rng):
    assert sp.simplify(scorbot_jacobian_q - gierlak_eq15()) == sp.zeros(6, 5)
    robot = wbc.load_robot("scorbot_er4pc")
    numeric = sp.lambdify(QS, scorbot_jacobian_q.subs(SCORBOT_VALUES))
    chain = np.array(DTHETA_DQ, dtype=float)
    for theta in rng.uniform(robot.lower, robot.upper, size=(100, 5)):
        q = np.array([theta[0], theta[1], theta[1] + theta[2], theta[1] + theta[2] + theta[3], theta[4]])
        np.testing.assert_allclose(np.array(numeric(*q), dtype=float), robot.frame_jacobian(theta, "ee") @ chain,
                                   rtol=0, atol=1e-12)


@pytest.mark.slow  # sympy derivation
def test_gierlaks_minors_eq20_are_right(scorbot_jacobian_q):
    poly, s, co = trig_to_symbols(scorbot_jacobian_q, QS)
    R = l1s + l2s * co[1] + l3s * co[2] + d5s * co[3]
    sin32 = s[2] * co[1] - co[2] * s[1]  # sin(q3 - q2)
    eq20 = [-l2s * l3s * R * sin32 * co[3], -l2s * l3s * R * s[0] * sin32 * s[3], l2s * l3s * R * co[0] * sin32 * s[3],
            0, l2s * l3s * co[0] * sin32 * co[3], l2s * l3s * s[0] * sin32 * co[3]]
    minors = list(maximal_minors(poly).values())  # rows deleted: 6, 5, 4, 3, 2, 1 (in that order)
    for ours, paper in zip(minors, eq20, strict=True):
        remainder = sp.reduced(sp.expand(ours - paper), [s[0] ** 2 + co[0] ** 2 - 1], s[0], co[0])[1]
        assert remainder == 0  # equal modulo sin^2 q1 + cos^2 q1 = 1


@pytest.mark.slow  # sympy derivation
def test_scorbot_true_singular_set(scorbot_jacobian_q):
    """Rows turned into the arm plane: the minors are l2 l3 sin(q3 - q2) (R cos q4, R sin q4, cos q4) up to sign.
    They vanish together iff sin(q3 - q2) = 0, or cos q4 = 0 and R = 0 (tool vertical on axis 1) -- not, as
    eq. (21) says, wherever any one factor of any one minor vanishes."""
    arm = sp.simplify(_arm_frame(scorbot_jacobian_q, QS[0]))
    poly, s, co = trig_to_symbols(arm, QS)
    R = l1s + l2s * co[1] + l3s * co[2] + d5s * co[3]
    sin32 = s[2] * co[1] - co[2] * s[1]
    nonzero = [m for m in maximal_minors(poly).values() if sp.expand(m) != 0]
    expected = [R * co[3], R * s[3], co[3]]
    assert len(nonzero) == len(expected)
    for e in expected:
        assert sum(sp.expand(m - sign * l2s * l3s * sin32 * e) == 0 for m in nonzero for sign in (1, -1)) == 1


SCORBOT_GENERIC_Q = np.array([0.4, 0.5, 1.1, -0.3, 0.7])  # paper angles q, full rank


def _scorbot_rank(q):
    robot = wbc.load_robot("scorbot_er4pc")
    theta = theta_from_q(q)
    assert robot.within_limits(theta)
    return rank(robot.frame_jacobian(theta, "ee"))


def _radius(q):
    g = SCORBOT
    return g["l1"] + g["l2"] * np.cos(q[1]) + g["l3"] * np.cos(q[2]) + g["d5"] * np.cos(q[3])


@pytest.mark.parametrize("label, index, value", [
    ("sin q1 = 0 (eq. 21)", 0, 0.0), ("cos q1 = 0 (eq. 21)", 0, np.pi / 2), ("sin q4 = 0 (eq. 21)", 3, 0.0),
    ("cos q4 = 0 (eq. 21, 23)", 3, np.pi / 2), ("sin q5 = 0 (eq. 23)", 4, 0.0), ("cos q5 = 0 (eq. 23)", 4, np.pi / 2),
])
def test_configurations_gierlak_calls_singular_have_full_rank(label, index, value):
    q = SCORBOT_GENERIC_Q.copy()
    q[index] = value
    assert _scorbot_rank(q) == 5, label


def test_radius_zero_alone_has_full_rank_but_with_vertical_tool_rank_4():
    g = SCORBOT
    q = np.array([0.4, 1.9, 0.0, 1.75, 0.7])  # tool tilted 10 deg off vertical
    q[2] = np.arccos(-(g["l1"] + g["l2"] * np.cos(q[1]) + g["d5"] * np.cos(q[3])) / g["l3"])
    assert abs(_radius(q)) < 1e-15 and abs(np.cos(q[3])) > 0.1
    assert _scorbot_rank(q) == 5  # R = 0 is in eq. (21), (23) but not singular on its own
    q = np.array([0.4, 1.9, 0.0, np.pi / 2, 0.7])
    q[2] = np.arccos(-(g["l1"] + g["l2"] * np.cos(q[1])) / g["l3"])
    assert abs(_radius(q)) < 1e-15
    assert _scorbot_rank(q) == 4
    q = SCORBOT_GENERIC_Q.copy()
    q[2] = q[1]  # sin(q3 - q2) = 0: elbow stretched
    assert _scorbot_rank(q) == 4


# ========================================================================= PUMA 560
TH6 = sp.symbols("theta1:7", real=True)
a2p, a3p, d3p, d4p = sp.symbols("a2 a3 d3 d4", positive=True)
PUMA_VALUES = {a2p: PUMA["a2"], a3p: PUMA["a3"], d3p: PUMA["d3"], d4p: PUMA["d4"]}


@pytest.fixture(scope="module")
def puma_frames():
    return dh_frames(puma_table(TH6, dict(a2=a2p, a3=a3p, d3=d3p, d4=d4p), pi=pi), lib=sp)


@pytest.mark.slow  # sympy derivation
def test_puma_determinant(puma_frames, rng):
    """At the wrist centre (= the ee origin, d6 = 0) the wrist joints add no linear velocity, so
    det J = det J11 det J22 = a2 (a3 s3 + d4 c3)(a2 c2 + a3 c23 - d4 s23) s5: elbow, shoulder, wrist."""
    J = symbolic_geometric_jacobian(puma_frames, puma_frames[4][:3, 3])
    robot = wbc.load_robot("puma560")
    numeric = sp.lambdify(TH6, J.subs(PUMA_VALUES))
    for q in rng.uniform(robot.lower, robot.upper, size=(50, 6)):
        np.testing.assert_allclose(np.array(numeric(*q), dtype=float), robot.frame_jacobian(q, "ee"),
                                   rtol=0, atol=1e-12)
    assert J[:3, 3:] == sp.zeros(3, 3)
    t2, t3, t5 = TH6[1], TH6[2], TH6[4]
    elbow = a3p * sp.sin(t3) + d4p * sp.cos(t3)
    shoulder = a2p * sp.cos(t2) + a3p * sp.cos(t2 + t3) - d4p * sp.sin(t2 + t3)
    assert sp.simplify(J[:3, :3].det() + a2p * elbow * shoulder) == 0
    assert sp.simplify(J[3:, 3:].det() + sp.sin(t5)) == 0


def test_puma_shoulder_condition_is_wrist_centre_at_distance_d3_from_axis_1(puma_frames):
    """|wrist centre - axis 1|^2 = shoulder^2 + d3^2: with the d3 offset the centre never reaches axis 1;
    the singularity is where it is closest, in the plane of axes 1 and 2."""
    centre = puma_frames[4][:3, 3]
    t2, t3 = TH6[1], TH6[2]
    shoulder = a2p * sp.cos(t2) + a3p * sp.cos(t2 + t3) - d4p * sp.sin(t2 + t3)
    assert sp.simplify(centre[0] ** 2 + centre[1] ** 2 - shoulder ** 2 - d3p ** 2) == 0


def test_puma_wrist_axes_4_and_6_align_exactly_at_theta5_zero(rng):
    """Lu et al.: the wrist is singular when axes 4 and 6 are collinear, i.e. theta5 = 0 -- confirmed."""
    robot = wbc.load_robot("puma560")
    for q in rng.uniform(robot.lower, robot.upper, size=(50, 6)):
        frames = dh_frames(puma_table(q))
        assert np.linalg.norm(np.cross(frames[3][:3, 2], frames[5][:3, 2])) == pytest.approx(abs(np.sin(q[4])),
                                                                                          abs=1e-12)


def test_puma_ranks_on_the_sets_and_their_intersections():
    g = PUMA
    elbow = np.arctan2(-g["d4"], g["a3"])  # the root within [-225, 45] deg

    def shoulder_theta2(t3):
        big_a = g["a2"] + g["a3"] * np.cos(t3) - g["d4"] * np.sin(t3)
        big_b = g["a3"] * np.sin(t3) + g["d4"] * np.cos(t3)
        return np.pi / 2 - np.arctan2(big_b, big_a)

    robot = wbc.load_robot("puma560")
    generic = np.array([0.3, 0.6, -0.8, 0.4, 0.9, 0.2])

    def moved(**joints):
        """A copy of ``generic`` with joint i set to the value passed as ``q<i>=``."""
        q = generic.copy()
        for name, value in joints.items():
            q[int(name[1:])] = value
        return q

    cases = {"generic": (generic, 6), "wrist": (moved(q4=0.0), 5), "elbow": (moved(q2=elbow), 5),
             "shoulder": (moved(q1=shoulder_theta2(generic[2])), 5)}
    for label, (q, expected) in cases.items():
        assert robot.within_limits(q), label
        assert rank(robot.frame_jacobian(q, "ee")) == expected, label
    # both positioning factors: J11 has rank 1, so rank J <= 1 + 3
    q = moved(q2=elbow, q1=shoulder_theta2(elbow))
    assert robot.within_limits(q) and rank(robot.frame_jacobian(q, "ee")) <= 4
    # a positioning factor and the wrist: J11 and J22 each lose one, but the coupling block J21 generally
    # restores one (rank 5); it does not for the elbow at theta4 = 0
    for t4, expected in ((0.4, 5), (0.0, 4)):
        q = moved(q2=elbow, q3=t4, q4=0.0)
        assert rank(robot.frame_jacobian(q, "ee")) == expected
