"""Collision pairs out of reach (wbc.collision.kernels._out_of_reach): the speed bound that the hard
constraints imply (written out), a pair left out only when no command within the hard constraints
can bind its damper (the worst case of its row written out as the LP's value, from coal's distances
and their finite differences), and the rule's threshold to within 0.01 %."""

import re

import numpy as np
import pinocchio as pin
import pytest

import wbc
from benchmarks.collision import obstacles
from conftest import bounding_sphere, pair_levers
from test_collision_distances import Oracle
from wbc.collision import RobotGeometry
from wbc.collision.avoidance import CollisionAvoidanceData
from wbc.collision.layout import HALF_EXTENTS, JOINT, ROTATION, TRANSLATION

YOUBOT = wbc.load_robot("youbot")
NEUTRAL = YOUBOT.neutral()
X, Y, HEADING = YOUBOT.base.indices
MIN_DISTANCE = 0.02


def _obstacles():
    """8 spheres and boxes around the platform and the arm (the benchmark's scene, another seed)."""
    return obstacles(8, seed=3)


def _keys(labels):
    """Link-pair keys of the oracle from wbc's labels ("arm_link_5↔box3" -> {arm_link_5, obstacle3})."""
    return {frozenset(re.sub(r"^(sphere|box|capsule|plane)(\d+)$", r"obstacle\2", part) for part in label.split("↔"))
            for label in labels}


def test_the_speed_bound_is_what_the_hard_constraints_imply():
    limit, linear = YOUBOT.velocity_limit, YOUBOT.base.max_linear_speed
    assert np.isfinite(linear) and np.all(np.isfinite(limit))
    expected = limit.copy()
    # the base rows bound |v_x|, |v_y| <= linear in the base frame: |xdot| <= |(v_x, v_y)| <= sqrt(2) linear
    expected[[X, Y]] = np.sqrt(2.0) * linear
    posture = [wbc.PostureTask(cost=1e-3)]
    limits = wbc.Controller(YOUBOT, posture, [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    np.testing.assert_allclose(limits.context.speed_bound, expected, rtol=1e-12)
    frozen = wbc.Controller(YOUBOT, posture, [wbc.JointVelocityLimits(), wbc.DofFreezing(["arm_joint_3"])])
    column = YOUBOT.model.joints[YOUBOT.model.getJointId("arm_joint_3")].idx_v
    expected[column] = 0.0
    np.testing.assert_allclose(frozen.context.speed_bound, expected, rtol=1e-12)
    # soft constraints and acceleration bounds (they change every tick) imply no constant speed bound
    unbounded = wbc.Controller(YOUBOT, posture, [wbc.JointPositionLimits(), wbc.AccelerationLimits(10.0)])
    assert np.all(unbounded.context.speed_bound == np.inf)
    puma = wbc.load_robot("puma560")
    fixed = wbc.Controller(puma, [wbc.PostureTask(cost=1e-3)], [wbc.JointVelocityLimits()])
    np.testing.assert_allclose(fixed.context.speed_bound, puma.velocity_limit, rtol=1e-12)


def _worst_rate(gradient, q):
    """max over the hard constraints (|v_k| <= limit_k; the base rows |v_x|, |v_y| <= linear in the
    base frame, v_x = c xdot + s ydot, v_y = -s xdot + c ydot) of -gradient . v: the LP's value."""
    limit, linear = YOUBOT.velocity_limit, YOUBOT.base.max_linear_speed
    others = [k for k in range(YOUBOT.nv) if k not in (X, Y)]
    c, s = np.cos(q[HEADING]), np.sin(q[HEADING])
    g_x, g_y = gradient[X], gradient[Y]
    return float(np.abs(gradient[others]) @ limit[others] + linear * (abs(c * g_x + s * g_y) + abs(-s * g_x + c * g_y)))


def _gradients(oracle, q, step=1e-6):
    """Central finite differences of every pair's coal distance along each velocity coordinate."""
    columns = []
    for k in range(YOUBOT.nv):
        e = np.zeros(YOUBOT.nv)
        e[k] = step
        ahead, behind = oracle.distances(YOUBOT.integrate(q, e, 1.0)), oracle.distances(YOUBOT.integrate(q, -e, 1.0))
        columns.append({key: (ahead[key] - behind[key]) / (2 * step) for key in ahead})
    return {key: np.array([column[key] for column in columns]) for key in columns[0]}


@pytest.mark.parametrize(("gain", "dt"), [(0.5, 0.01), (1.0, 0.005), (0.5, 0.02)])
def test_a_pair_is_left_out_only_when_no_command_can_bind_its_row(gain, dt):
    obstacles = _obstacles()
    avoidance = wbc.CollisionAvoidance(obstacles, min_distance=MIN_DISTANCE, detection_distance=0.3, gain=gain)
    controller = wbc.Controller(YOUBOT, [wbc.PostureTask(cost=1e-3)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), avoidance], dt=dt)
    data = controller.data(avoidance)
    oracle = Oracle(YOUBOT, obstacles)
    excluded = {frozenset((e.link_a, e.link_b)) for e in RobotGeometry(YOUBOT).excluded}
    rng = np.random.default_rng(11)
    checked, obstacle_pairs, kept = 0, 0, 0
    for _ in range(12):
        q = YOUBOT.random_configuration(rng, base_range=0.3)
        controller.step(q)
        found = _keys(data.active_labels())
        distances = oracle.distances(q)
        near = {key for key, d in distances.items() if d < 0.3 and key not in excluded}
        kept += len(found)
        assert all(distances[key] < 0.3 + 1e-6 for key in found)  # no row for a far pair
        left_out = near - found
        if not left_out:
            continue
        gradients = _gradients(oracle, q)
        for key in left_out:
            d = distances[key]
            # its damper d_dot >= -gain (d - d_min) / dt holds for every command the hard constraints allow
            assert _worst_rate(gradients[key], q) <= gain * (d - MIN_DISTANCE) / dt + 1e-4, (key, d)
            checked += 1
            obstacle_pairs += any(name.startswith("obstacle") for name in key)
    assert checked >= 20 and obstacle_pairs >= 5 and kept > 0  # the rule left pairs out, of both kinds, and kept some


def _reach_of(a, b, table, q, speed):
    """``sum_k speed_k (|v_O,k + w_k x c| + |w_k| r)`` over the coordinates that move only one of
    shapes a and b (its bounding sphere c, r; conftest.pair_levers, Pinocchio's world joint
    Jacobians); and the pair's bounding-sphere distance ``|c_a - c_b| - r_a - r_b``."""
    model, data = YOUBOT.model, YOUBOT.model.createData()
    pin.computeJointJacobians(model, data, q)
    levers, spheres = pair_levers(model, data, table, a, b)
    moved = ~np.isnan(levers)
    (c_a, r_a), (c_b, r_b) = spheres
    return float(speed[moved] @ levers[moved]), float(np.linalg.norm(c_a - c_b) - r_a - r_b), spheres[0]


@pytest.mark.parametrize(("link_a", "link_b"), [("arm_link_3", "sphere"), ("arm_link_5", "sphere"),
                                                ("arm_link_2", "arm_link_5"), ("arm_link_1", "arm_link_4")])
def test_the_pair_is_left_out_just_past_its_reach(link_a, link_b):
    """The rule's threshold: the gain at which ``gain (bound - d_min) / dt`` equals the pair's reach
    (written out above), crossed by 0.01 % either way. A self pair's reach is the moving side's;
    (arm_link_5: its first shape)."""
    q = NEUTRAL.copy()
    q[HEADING] = 0.4
    q[YOUBOT.model.joints[YOUBOT.model.getJointId("arm_joint_3")].idx_q] = -1.2  # the forearm folded back
    geometry = RobotGeometry(YOUBOT)
    links = list(geometry.links)
    a = links.index(link_a)
    speed = np.array(YOUBOT.velocity_limit)
    speed[[X, Y]] = np.sqrt(2.0) * YOUBOT.base.max_linear_speed
    obstacles = []
    table = geometry.table
    if link_b == "sphere":  # 0.12 m beyond the shape's bounding sphere, straight up
        data = YOUBOT.model.createData()
        pin.forwardKinematics(YOUBOT.model, data, q)
        centre, radius = bounding_sphere(table, a, data.oMi)
        obstacles = [wbc.Sphere(centre + (0.0, 0.0, radius + 0.12 + 0.03), 0.03)]
        table = wbc.collision.Distances(YOUBOT, obstacles, geometry=geometry).table
        b = len(links)
    else:
        b = links.index(link_b)
    reach, bound, _ = _reach_of(a, b, table, q, speed)
    assert reach > 0.0 and bound > MIN_DISTANCE + 0.01
    dt = 0.5 * (bound - MIN_DISTANCE) / reach  # then the threshold gain is 0.5
    present = {}
    for factor in (1.0 - 1e-4, 1.0 + 1e-4):
        avoidance = wbc.CollisionAvoidance(obstacles, self_collision=link_b != "sphere", min_distance=MIN_DISTANCE,
                                           detection_distance=2.0, gain=0.5 * factor)
        controller = wbc.Controller(YOUBOT, [wbc.PostureTask(cost=1e-3)], [wbc.JointVelocityLimits(), avoidance],
                                    dt=dt)
        controller.step(q)
        data = controller.data(avoidance)
        pairs = data.distances.pairs[data.pairs.pair[:data.pairs.count]]
        present[factor] = bool(np.any((pairs[:, 0] == a) & (pairs[:, 1] == b)))
    assert present == {1.0 - 1e-4: True, 1.0 + 1e-4: False}


def test_the_commands_are_those_with_every_pair(monkeypatch):
    """Leaving the pairs out of reach changes the work, not the commands: a closed loop against
    the same controller whose every pair within the detection distance gets its row."""
    def controller():
        ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.1, gain=0.5)
        pose = YOUBOT.frame_pose(NEUTRAL, "ee")
        pose[:3, 3] += (0.45, 0.25, -0.2)
        ee.set_target(pose)
        avoidance = wbc.CollisionAvoidance(_obstacles())
        return wbc.Controller(YOUBOT, [ee, wbc.PostureTask(cost=1e-3, gain=0.05)],
                              [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), avoidance]), avoidance

    reach, avoidance = controller()
    with monkeypatch.context() as patch:
        patch.setattr(CollisionAvoidanceData, "_speed", property(lambda data: data._unbounded))
        every, every_avoidance = controller()
        q, fewer = NEUTRAL.copy(), 0
        for _ in range(300):
            v = reach.step(q)
            np.testing.assert_allclose(every.step(q), v, rtol=0.0, atol=1e-9)
            assert reach.last.status == every.last.status
            fewer += every.data(every_avoidance).pairs.count - reach.data(avoidance).pairs.count
            q = YOUBOT.integrate(q, v, 0.01)
    assert fewer > 300  # pairs were left out on most ticks


def test_the_reach_bounds_the_relative_speed_of_any_two_points_of_the_spheres(rng):
    """What the tie rows of a pair rely on (wbc.collision.kernels._corner_rows: twice the pair's
    reach as their speed): for any point of each bounding sphere -- a capsule's ends among them --
    the largest rate of their distance, ``n . (v_b(p_b) - v_a(p_a))`` with ``n`` from p_a to p_b,
    over ``|v_k| <= speed_k`` (the LP's value, from Pinocchio's joint Jacobians) is at most the
    pair's reach (written out above), for self pairs (a shared coordinate moves both points
    rigidly: no change along n) and obstacle pairs."""
    geometry = RobotGeometry(YOUBOT)
    links = list(geometry.links)
    obstacles = _obstacles()
    table = wbc.collision.Distances(YOUBOT, obstacles, geometry=geometry).table
    speed = np.array(YOUBOT.velocity_limit)
    speed[[X, Y]] = np.sqrt(2.0) * YOUBOT.base.max_linear_speed
    model, data = YOUBOT.model, YOUBOT.model.createData()
    shapes = range(table.shape[0])
    tight = 0
    for _ in range(20):
        q = YOUBOT.random_configuration(rng, base_range=0.3)
        pin.computeJointJacobians(model, data, q)
        for _ in range(10):
            a, b = (int(s) for s in rng.choice(len(links), 2, replace=False)) if rng.random() < 0.5 else (
                int(rng.integers(len(links))), int(rng.integers(len(links), len(shapes))))
            reach, _, _ = _reach_of(a, b, table, q, speed)
            jacobians = [pin.getJointJacobian(model, data, int(table[s, JOINT]), pin.ReferenceFrame.WORLD)
                         for s in (a, b)]
            for _ in range(5):
                points = []
                for s in (a, b):
                    centre, radius = bounding_sphere(table, s, data.oMi)
                    direction = rng.normal(size=3)
                    points.append(centre + radius * rng.random() ** (1 / 3) * direction / np.linalg.norm(direction))
                n = (points[1] - points[0]) / np.linalg.norm(points[1] - points[0])
                rate = np.zeros(YOUBOT.nv)
                for sign, point, jacobian in ((-1.0, points[0], jacobians[0]), (1.0, points[1], jacobians[1])):
                    rate += sign * (n @ (jacobian[:3] + np.cross(jacobian[3:].T, point).T))
                worst = float(np.abs(rate) @ speed)
                assert worst <= reach * (1 + 1e-12) + 1e-12, (links[a], b, worst, reach)
                tight += worst > 0.5 * reach
    assert tight > 50  # the bound is not vacuous: often within a factor 2


@pytest.mark.parametrize("gap", [0.12, 0.25])
def test_the_bounding_spheres_leave_a_pair_out_just_past_its_reach(gap):
    """The broad phase's cutoff (wbc.collision.kernels._cutoff: ``d_min + reach / rate``, applied to
    the bounding spheres before any other bound): a sphere on the platform's diagonal through a top
    corner, ``gap`` beyond it, where the bounding spheres' distance is the pair's distance, and the
    heading frozen, so that the pair's reach over every configuration (the cutoff's) is its reach
    here (``speed_x + speed_y``: the base translates the platform): the pair is kept 1e-6 inside the
    threshold gain and left out 1e-6 beyond it. (Where the two reaches differ, the exact rule
    decides the pairs near the threshold and the cutoff is invisible, as it should be.)"""
    q = NEUTRAL.copy()
    q[[X, Y, HEADING]] = 0.3, -0.2, 0.4
    geometry = RobotGeometry(YOUBOT)
    a = list(geometry.links).index("base_link")
    table = geometry.table
    kinematics = YOUBOT.model.createData()
    pin.forwardKinematics(YOUBOT.model, kinematics, q)
    centre, radius = bounding_sphere(table, a, kinematics.oMi)
    corner = kinematics.oMi[int(table[a, JOINT])].act(table[a, TRANSLATION]
                                                + table[a, ROTATION].reshape(3, 3) @ table[a, HALF_EXTENTS])
    assert np.linalg.norm(corner - centre) == pytest.approx(radius, abs=1e-12)  # the sphere through the corners
    direction = (corner - centre) / radius
    obstacles = [wbc.Sphere(corner + (gap + 0.03) * direction, 0.03)]
    table = wbc.collision.Distances(YOUBOT, obstacles, geometry=geometry).table
    b = len(geometry.links)
    speed = np.array(YOUBOT.velocity_limit)
    speed[[X, Y]] = np.sqrt(2.0) * YOUBOT.base.max_linear_speed
    speed[HEADING] = 0.0  # frozen
    reach, bound, _ = _reach_of(a, b, table, q, speed)
    assert reach == pytest.approx(speed[X] + speed[Y], rel=1e-12)
    assert bound == pytest.approx(gap, abs=1e-12)  # the corner is the platform's point nearest the sphere
    dt = 0.5 * (gap - MIN_DISTANCE) / reach  # then the threshold gain is 0.5
    present = {}
    for factor in (1.0 - 1e-6, 1.0 + 1e-6):
        avoidance = wbc.CollisionAvoidance(obstacles, self_collision=False, min_distance=MIN_DISTANCE,
                                           detection_distance=0.3, gain=0.5 * factor)
        controller = wbc.Controller(YOUBOT, [wbc.PostureTask(cost=1e-3)],
                                    [wbc.JointVelocityLimits(), wbc.DofFreezing(["base_yaw"]), avoidance], dt=dt)
        controller.step(q)
        data = controller.data(avoidance)
        np.testing.assert_allclose(data._reach[YOUBOT.nv:][data.distances.pairs[:, 0] == a], reach, rtol=1e-8)
        entries = data.pairs.count
        pairs = data.distances.pairs[data.pairs.pair[:entries]]
        entry = np.flatnonzero((pairs[:, 0] == a) & (pairs[:, 1] == b))
        present[factor] = entry.size > 0
        if present[factor]:
            assert data.pairs.distance[entry[0]] == pytest.approx(gap, abs=1e-9)
    assert present == {1.0 - 1e-6: True, 1.0 + 1e-6: False}
