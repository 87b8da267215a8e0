"""wbc.CollisionAvoidance in wbc.Controller: the rows (a formula written out against coal's
distances), closed loops checked every tick against coal (Pinocchio computeDistances on the
URDF's raw shapes), a robot pushed out of the margin, bad input."""

import copy
import pickle
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import wbc
from test_collision_distances import Oracle
from wbc.collision import RobotGeometry
from wbc.collision.avoidance import CORNER_ROWS
from wbc.constraints.constraint import ConstraintRows
from wbc.model.kinematics import Kinematics

MIN_DISTANCE = 0.02
#: the damper holds d >= min_distance to first order; the second-order term of a tick at the
#: speeds of these tests (joints up to ~1.5 rad/s, dt = 0.01) costs up to this much [m]
TOLERANCE = 2e-3
YOUBOT = wbc.load_robot("youbot")
NEUTRAL = YOUBOT.neutral()
EE = YOUBOT.frame_pose(NEUTRAL, "ee")[:3, 3]
LIMITS = (wbc.JointPositionLimits(), wbc.JointVelocityLimits())


def _closest(oracle, excluded, q):
    """The smallest coal distance over the pairs the constraint covers (excluded pairs left out)."""
    return min(d for key, d in oracle.distances(q).items() if key not in excluded)


def _excluded(robot):
    return {frozenset((e.link_a, e.link_b)) for e in RobotGeometry(robot).excluded}


def _run(controller, q, ticks, oracle, excluded):
    """Closed loop (Euler); the coal distance after every tick and the statuses seen."""
    closest, statuses = [], set()
    for _ in range(ticks):
        q = controller.robot.integrate(q, controller.step(q), 0.01)
        statuses.add(controller.last.status)
        closest.append(_closest(oracle, excluded, q))
    return q, np.array(closest), statuses


def _reach(target, avoidance, solver="daqp", limits=LIMITS):
    ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.0, gain=0.5, max_speed=0.5)
    pose = YOUBOT.frame_pose(NEUTRAL, "ee")
    pose[:3, 3] = target
    ee.set_target(pose)
    constraints = [*limits, avoidance] if avoidance is not None else list(limits)
    return wbc.Controller(YOUBOT, [ee, wbc.PostureTask(cost=1e-3, gain=0.05)], constraints, solver=solver)


def test_rows_are_the_velocity_damper_of_each_close_pair():
    sphere = wbc.Sphere(EE + (0.1, 0.0, 0.0), 0.05)
    avoidance = wbc.CollisionAvoidance([sphere], min_distance=0.02, detection_distance=0.3, gain=0.4)
    data = avoidance.bind(YOUBOT)
    n = data.n_inequalities
    rows = ConstraintRows(np.full(YOUBOT.nv, -np.inf), np.full(YOUBOT.nv, np.inf), np.full((n, YOUBOT.nv), 7.0),
                          np.full(n, 7.0), np.zeros((0, YOUBOT.nv)), np.zeros(0))
    data.write_static(rows)
    kin = Kinematics(YOUBOT)
    q = YOUBOT.random_configuration(np.random.default_rng(5), base_range=0.2) * 0.3
    kin.update(q)
    dt = 0.02
    data.compute(kin, dt, rows)
    count = data.pairs.count
    assert 0 < count < n
    oracle = Oracle(YOUBOT, [sphere]).distances(q)
    for i, label in enumerate(data.active_labels()):
        key = frozenset(label.replace("sphere0", "obstacle0").split("↔"))
        # the oracle has the closest shapes of the two links (the gripper has two shapes)
        assert data.pairs.distance[i] >= oracle[key] - 1e-6
        assert rows.h[i] == pytest.approx(0.4 * (data.pairs.distance[i] - 0.02) / dt)
        np.testing.assert_array_equal(rows.G[i], -data.pairs.rows[i])
    corners = data.corners
    assert corners > 0  # the capsules' ends
    checked = 0
    for j, i in enumerate(data.corner_pair[:corners].tolist()):
        # a capsule end's distance is at least the pair's, at most 5 m/s * dt more
        gap = rows.h[count + j] * dt / 0.4 + 0.02
        assert data.pairs.distance[i] - 1e-12 <= gap <= data.pairs.distance[i] + 5.0 * dt + 1e-12
        checked += _check_corner_row(data, i, gap, rows.G[count + j], q, sphere)
    assert checked > 0
    end = count + corners
    assert np.all(rows.G[end:] == 0.0) and np.all(rows.h[end:] == 1.0)  # inert: 0 <= 1


def _check_corner_row(data, i, gap, row, q, sphere) -> bool:
    """A capsule end's row against finite differences of that end's distance to the sphere,
    ``|p(q) - c| - R - r`` (p: the end of robot link a's capsule, the sphere still)."""
    pair = data.distances.pairs[data.pairs.pair[i]]
    table = data.distances.table
    if table[pair[1], 1] != 0:  # a self pair: both move; the sphere pairs suffice here
        return False
    import pinocchio as pin
    model, pdata = YOUBOT.model, YOUBOT.model.createData()
    joint, radius = int(table[pair[0], 1]), table[pair[0], 14]
    pin.forwardKinematics(model, pdata, q)
    world = data.distances._world[pair[0]]
    axis, centre = world[[2, 5, 8]], world[9:12]

    def distance(p):
        return np.linalg.norm(p - sphere.center) - sphere.radius - radius

    ends = [centre + sign * table[pair[0], 15] * axis for sign in (1.0, -1.0)]
    end = min(ends, key=lambda e: abs(distance(e) - gap))
    assert distance(end) == pytest.approx(gap, abs=1e-9)
    local = pdata.oMi[joint].actInv(end)
    for k in range(YOUBOT.nv):
        step = np.zeros(YOUBOT.nv)
        step[k] = 1e-6
        pin.forwardKinematics(model, pdata, pin.integrate(model, q, step))
        rate = (distance(pdata.oMi[joint].act(local)) - distance(end)) / 1e-6
        assert -row[k] == pytest.approx(rate, abs=1e-5)
    return True


def test_every_pair_within_detection_gets_a_row_and_no_other():
    """Without speed limits no pair is out of reach (tests/test_collision_reach.py: with them)."""
    sphere = wbc.Sphere(EE + (0.15, 0.0, 0.0), 0.05)
    avoidance = wbc.CollisionAvoidance([sphere], detection_distance=0.12)
    controller = _reach(EE, avoidance, limits=(wbc.JointPositionLimits(),))
    assert np.all(controller.context.speed_bound == np.inf)
    data = controller.data(avoidance)
    controller.step(NEUTRAL)
    expected = {key for key, d in Oracle(YOUBOT, [sphere]).distances(NEUTRAL).items()
                if d < 0.12 and key not in _excluded(YOUBOT)}
    found = {frozenset(label.replace("sphere0", "obstacle0").split("↔")) for label in data.active_labels()}
    assert found == expected and len(expected) >= 2


def test_the_row_count_is_fixed():
    sphere = wbc.Sphere((5.0, 0.0, 0.0), 0.1)
    avoidance = wbc.CollisionAvoidance([sphere])
    controller = _reach(EE + (0.2, 0.0, -0.2), avoidance, limits=(wbc.JointPositionLimits(),))  # none out of reach
    data = controller.data(avoidance)
    geometry = RobotGeometry(YOUBOT)
    candidates = len(geometry.pairs) + geometry.size  # self pairs + every moving shape against the sphere
    assert data.n_inequalities == candidates + CORNER_ROWS  # a row per pair, a budget for the corners
    q = NEUTRAL.copy()
    for _ in range(3):
        q = YOUBOT.integrate(q, controller.step(q), 0.01)
    assert data.pairs.count == data.distances.compute(q, data.distances.buffers())  # far sphere: self pairs only
    sphere.center = EE  # moved between ticks: now in contact with the gripper
    controller.step(q)
    assert any("sphere0" in label for label in data.active_labels())
    assert data.n_inequalities == candidates + CORNER_ROWS


@pytest.mark.parametrize("solver", wbc.available_solvers())
def test_gripper_path_straight_through_a_sphere_keeps_the_margin(solver):
    sphere = wbc.Sphere(EE + (0.15, 0.0, -0.05), 0.05)
    target = EE + (0.3, 0.0, -0.1)  # the straight path passes through the sphere's centre
    oracle, excluded = Oracle(YOUBOT, [sphere]), _excluded(YOUBOT)
    q, closest, statuses = _run(_reach(target, wbc.CollisionAvoidance([sphere])), NEUTRAL, 300, oracle, excluded)
    assert closest.min() >= MIN_DISTANCE - TOLERANCE
    assert "optimal" in statuses  # (ProxQP: a few ticks from the elastic fallback, 1e-6 off optimal)
    assert np.linalg.norm(YOUBOT.frame_pose(q, "ee")[:3, 3] - target) < 1e-3  # it went around
    _, unguarded, _ = _run(_reach(target, None), NEUTRAL, 300, oracle, excluded)
    assert unguarded.min() < 0.0  # without the constraint the gripper goes through the sphere


@pytest.mark.parametrize("target", [(1.5, 2.5, 0.0), (1.5, 1.2, 1.5), (-1.1, -2.5, -1.7)])
def test_youbot_arm_folded_onto_its_platform_stops_short(target):
    posture = wbc.PostureTask(cost=1.0, gain=0.3, target=np.array([0, 0, 0, 0, *target, 0.0]))
    oracle, excluded = Oracle(YOUBOT, []), _excluded(YOUBOT)
    guarded = wbc.Controller(YOUBOT, [posture], [*LIMITS, wbc.CollisionAvoidance()])
    _, closest, _ = _run(guarded, NEUTRAL, 250, oracle, excluded)
    assert closest.min() >= MIN_DISTANCE - TOLERANCE
    assert closest[-1] < MIN_DISTANCE + 0.01  # it went as far as the margin lets it
    _, unguarded, _ = _run(wbc.Controller(YOUBOT, [posture], list(LIMITS)), NEUTRAL, 250, oracle, excluded)
    assert unguarded.min() < 0.0


@pytest.mark.parametrize("solver", ["daqp", "quadprog"])
def test_a_robot_inside_the_margin_is_pushed_out(solver):
    sphere = wbc.Sphere(EE + (0.05, 0.0, -0.06), 0.05)  # overlaps the gripper from the side: d < 0
    oracle, excluded = Oracle(YOUBOT, [sphere]), _excluded(YOUBOT)
    start = _closest(oracle, excluded, NEUTRAL)
    assert start < 0.0
    hold = wbc.PostureTask(cost=1e-2, gain=0.5, target=NEUTRAL)  # pulls back toward the start
    controller = wbc.Controller(YOUBOT, [hold], [*LIMITS, wbc.CollisionAvoidance([sphere])], solver=solver)
    _, closest, _ = _run(controller, NEUTRAL, 100, oracle, excluded)
    assert closest[0] > start  # moving from the first tick on, not frozen
    assert closest[-1] >= MIN_DISTANCE - TOLERANCE
    later = np.flatnonzero(closest >= MIN_DISTANCE - TOLERANCE)[0]
    assert np.all(closest[later:] >= MIN_DISTANCE - TOLERANCE)


@pytest.mark.parametrize("overlap", [0.02, -0.01])
def test_the_platform_is_pushed_out_of_a_crate(overlap):
    """The platform (a box) starting 2 cm into a crate (a box: the separating-axis depth), or 1 cm
    from it (inside the 2 cm margin), on the native tick with the rows an op: moving away from the
    first tick (the coal distance grows every tick until it reaches the margin, then stays above
    it), every command finite and within the joint speed limits. 2 cm in, the damper asks for an
    escape of gain (d_min - d) / dt = 2 m/s, more than the base's 0.8: those first ticks are the
    elastic fallback's, which names the conflict and pushes out at the speed limit; 1 cm out it
    asks 0.5 m/s: every tick optimal."""
    crate = _box((0.29 + 0.1 - overlap, 0.0, -0.06), (0.2, 0.2, 0.08))  # the platform's front face at x = 0.29
    oracle, excluded = Oracle(YOUBOT, [crate]), _excluded(YOUBOT)
    assert _closest(oracle, excluded, NEUTRAL) == pytest.approx(-overlap, abs=1e-9)
    hold = wbc.PostureTask(cost=1e-2, gain=0.5, target=NEUTRAL)  # pulls back into the crate
    avoidance = wbc.CollisionAvoidance([crate])
    controller = wbc.Controller(YOUBOT, [hold], [*LIMITS, avoidance])
    assert controller._stepper is not None  # the whole tick one native call
    assert not any(isinstance(data, type(controller.data(avoidance))) for data, _ in controller._python_constraints)
    limit = YOUBOT.velocity_limit
    q, closest, elastic = NEUTRAL, [], []
    for _ in range(60):
        v = controller.step(q)
        last = controller.last
        assert np.all(np.isfinite(v)) and np.all(np.abs(v) <= limit + 1e-9)
        if not last.success:
            assert last.outcome is wbc.Outcome.ELASTIC and v[0] == pytest.approx(-limit[0])
            assert sorted(last.conflicts) == ["CollisionAvoidance: base_link↔box0",
                                              "JointVelocityLimits: base v_x lower"]
        elastic.append(not last.success)
        q = YOUBOT.integrate(q, v, 0.01)
        closest.append(_closest(oracle, excluded, q))
    closest = np.array(closest)
    reached = int(np.flatnonzero(closest >= MIN_DISTANCE - TOLERANCE)[0])
    assert np.all(np.diff(closest[:reached + 1]) > 0.0)  # pushed out every tick, never frozen
    assert np.all(closest[reached:] >= MIN_DISTANCE - TOLERANCE)
    fallbacks = int(np.sum(elastic))
    assert not any(elastic[fallbacks:])  # a run of first ticks
    assert (fallbacks > 0) == (overlap > 0)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(st.floats(0.05, 0.3), st.floats(-0.15, 0.15), st.floats(-0.25, 0.05), st.floats(0.03, 0.1),
       st.sampled_from(["sphere", "box", "capsule"]))
def test_random_obstacles_are_never_entered(x, y, z, size, kind):
    centre = EE + (x, y, z)
    if kind == "sphere":
        obstacle = wbc.Sphere(centre, size)
    elif kind == "box":
        pose = np.eye(4)
        pose[:3, 3] = centre
        obstacle = wbc.Box(pose, (size, 2 * size, size))
    else:
        obstacle = wbc.Capsule(centre - (0.0, size, 0.0), centre + (0.0, size, 0.0), size / 2)
    oracle, excluded = Oracle(YOUBOT, [obstacle]), _excluded(YOUBOT)
    if _closest(oracle, excluded, NEUTRAL) < MIN_DISTANCE:
        return  # starts inside the margin: test_a_robot_inside_the_margin_is_pushed_out
    controller = _reach(EE + (0.3, 0.0, -0.15), wbc.CollisionAvoidance([obstacle]))
    _, closest, _ = _run(controller, NEUTRAL, 150, oracle, excluded)
    assert closest.min() >= MIN_DISTANCE - TOLERANCE


def _box(centre, size):
    pose = np.eye(4)
    pose[:3, 3] = centre
    return wbc.Box(pose, size)


@pytest.mark.parametrize("case", ["witness at an end", "witness inside", "overlapping capsules"])
def test_a_capsule_parallel_to_an_edge_does_not_chatter_into_the_margin(case):
    """A capsule parallel to an edge or to another capsule: its closest point ties between points
    far apart. With the witness row alone the QP turned one end away while the other approached,
    the witness jumped, and the command reversed every tick at full speed into the margin: the
    gripper's cross capsule along the box's top edge with the witness at one end (18.3 mm of the 20
    mm margin), with the witness inside the capsule (the cross capsule along a box edge, the wrist
    reversing at 1.57 rad/s: 17.74 mm) and along an overlapping capsule (19.12 mm). The end rows
    (a damper per end, and per overhang point on a box: :func:`wbc.collision.kernels.corner_rows`)
    keep the margin and stop it."""
    centre = {"witness at an end": EE + (0.28125, 0.0, -0.25), "witness inside": EE + (0.219, -0.039, -0.231),
              "overlapping capsules": EE + (0.198, -0.046, -0.177)}[case]
    if case == "witness at an end":
        obstacle = _box(centre, (0.0625, 0.125, 0.0625))
    elif case == "witness inside":
        obstacle = _box(centre, (0.066, 0.132, 0.066))
    else:
        obstacle = wbc.Capsule(centre - (0.0, 0.057, 0.0), centre + (0.0, 0.057, 0.0), 0.0285)
    oracle, excluded = Oracle(YOUBOT, [obstacle]), _excluded(YOUBOT)
    controller = _reach(EE + (0.3, 0.0, -0.15), wbc.CollisionAvoidance([obstacle]))
    q, commands, closest = NEUTRAL.copy(), [], []
    for _ in range(150):
        v = controller.step(q)
        q = YOUBOT.integrate(q, v, 0.01)
        commands.append(v)
        closest.append(_closest(oracle, excluded, q))
    assert min(closest) >= MIN_DISTANCE - 5e-4
    late = np.array(commands[100:])
    flips = (late[1:] * late[:-1] < 0.0) & (np.abs(late[1:]) > 0.1) & (np.abs(late[:-1]) > 0.1)
    assert not np.any(flips)  # no coordinate reverses a command above 0.1 (rad, m)/s between two ticks


def test_moving_obstacle_pushes_the_arm_away():
    sphere = wbc.Sphere(EE + (0.3, 0.0, 0.0), 0.05)
    hold = wbc.PostureTask(cost=1e-2, gain=0.5, target=NEUTRAL)
    controller = wbc.Controller(YOUBOT, [hold], [*LIMITS, wbc.CollisionAvoidance([sphere])])
    oracle_q, q = [], NEUTRAL.copy()
    for k in range(150):
        sphere.center = EE + (0.3 - 0.002 * k, 0.0, 0.0)  # 0.2 m/s toward the gripper
        q = YOUBOT.integrate(q, controller.step(q), 0.01)
        oracle_q.append(_closest(Oracle(YOUBOT, [sphere]), _excluded(YOUBOT), q))
    # the damper assumes a still obstacle: the approach speed of 2 mm per tick is the slack it needs
    assert min(oracle_q) >= MIN_DISTANCE - TOLERANCE - 0.002
    assert _closest(Oracle(YOUBOT, [sphere]), _excluded(YOUBOT), NEUTRAL) < 0.0  # it would have been hit


def test_bad_input_is_refused():
    with pytest.raises(wbc.InvalidInputError, match="min_distance"):
        wbc.CollisionAvoidance(min_distance=-0.01)
    with pytest.raises(wbc.InvalidInputError, match="below detection_distance"):
        wbc.CollisionAvoidance(min_distance=0.3, detection_distance=0.2)
    with pytest.raises(wbc.InvalidInputError, match="gain"):
        wbc.CollisionAvoidance(gain=0.0)
    with pytest.raises(wbc.InvalidInputError, match="obstacles"):
        wbc.CollisionAvoidance(obstacles=[(0, 0, 0)])
    with pytest.raises(wbc.InvalidInputError, match="self_collision"):
        wbc.CollisionAvoidance(self_collision="yes")
    with pytest.raises(wbc.InvalidInputError, match="capacity"):
        wbc.CollisionAvoidance(capacity=0)
    with pytest.raises(wbc.InvalidInputError, match="Sphere center"):
        wbc.Sphere((np.nan, 0, 0), 0.1)
    with pytest.raises(wbc.InvalidInputError, match="Sphere radius"):
        wbc.Sphere((0, 0, 0), -0.1)
    with pytest.raises(wbc.InvalidInputError, match="Box size"):
        wbc.Box(np.eye(4), (0.1, 0.0, 0.1))
    with pytest.raises(wbc.InvalidInputError, match="Plane normal"):
        wbc.Plane((0, 0, 0), 1.0)
    avoidance = wbc.CollisionAvoidance()
    with pytest.raises(wbc.InvalidInputError, match="below detection_distance"):
        avoidance.min_distance = 0.5
    assert avoidance.min_distance == 0.02  # unchanged
    sphere = wbc.Sphere((0, 0, 0), 0.1)
    with pytest.raises(wbc.InvalidInputError, match="Sphere center"):
        sphere.center = (0, np.inf, 0)
    np.testing.assert_array_equal(sphere.center, (0, 0, 0))  # kept its place


def test_huge_obstacles_are_placed_exactly_or_refused_without_a_numpy_warning():
    """Values near the float range: norms and differences computed without overflow (numpy's
    RuntimeWarning leaked; a plane's 1e200 normal was called zero)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plane = wbc.Plane((1e200, 1e200, 0.0), 1e200)  # |n| = sqrt(2) 1e200: the plane x + y = sqrt(2)
        np.testing.assert_allclose(plane.normal, [2 ** -0.5, 2 ** -0.5, 0.0], rtol=1e-15)
        assert plane.offset == pytest.approx(2 ** -0.5, rel=1e-15)
        with pytest.raises(wbc.InvalidInputError, match="Plane normal .* too long .* give a unit normal"):
            wbc.Plane((1.5e308, 1.5e308, 0.0), 0.0)  # |n| overflows
        capsule = wbc.Capsule((-1e154, 0.0, 0.0), (1e154, 0.0, 0.0), 0.05)  # |p1 - p0|^2 overflows
        np.testing.assert_array_equal(capsule.points[0], [-1e154, 0.0, 0.0])
        np.testing.assert_array_equal(capsule.points[1], [1e154, 0.0, 0.0])
        with pytest.raises(wbc.InvalidInputError, match="Capsule p0, p1 are too far apart"):
            wbc.Capsule((-1e308, 0.0, 0.0), (1e308, 0.0, 0.0), 0.05)  # p1 - p0 overflows
        box = wbc.Box(np.eye(4), (1e300, 1e300, 1e300))  # its bounding radius overflows: never culled
        np.testing.assert_array_equal(box.size, [1e300] * 3)


def test_a_urdf_without_collision_geometry_is_refused_when_the_controller_is_built(tmp_path):
    source = Path(YOUBOT.source).read_text()
    (tmp_path / "bare.urdf").write_text(re.sub(r"<collision>\s*<.*?</collision>", "", source, flags=re.S))
    bare = wbc.load_robot(tmp_path / "bare.urdf")
    with pytest.raises(wbc.ModelError, match="no collision geometry"):
        wbc.Controller(bare, [wbc.PostureTask(cost=1.0)], [wbc.CollisionAvoidance()])


def test_copies_carry_their_own_obstacles():
    sphere = wbc.Sphere((0.5, 0.0, 0.3), 0.1)
    avoidance = wbc.CollisionAvoidance([sphere], min_distance=0.05)
    for duplicate in (copy.deepcopy(avoidance), pickle.loads(pickle.dumps(avoidance))):
        assert duplicate.min_distance == 0.05 and duplicate.obstacles[0].radius == 0.1
        duplicate.obstacles[0].center = (1.0, 0.0, 0.0)
        np.testing.assert_array_equal(sphere.center, (0.5, 0.0, 0.3))


def test_strict_priorities_keep_the_margin():
    sphere = wbc.Sphere(EE + (0.15, 0.0, -0.05), 0.05)
    ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.0, gain=0.5, max_speed=0.5)
    pose = YOUBOT.frame_pose(NEUTRAL, "ee")
    pose[:3, 3] = EE + (0.3, 0.0, -0.1)
    ee.set_target(pose)
    controller = wbc.Controller(YOUBOT, [[ee], [wbc.PostureTask(cost=1e-3, gain=0.05)]],
                                [*LIMITS, wbc.CollisionAvoidance([sphere])])
    q, closest, _ = _run(controller, NEUTRAL, 300, Oracle(YOUBOT, [sphere]), _excluded(YOUBOT))
    assert closest.min() >= MIN_DISTANCE - TOLERANCE
    assert np.linalg.norm(YOUBOT.frame_pose(q, "ee")[:3, 3] - pose[:3, 3]) < 1e-3


@pytest.mark.parametrize("reduced", [False, True])
def test_nonholonomic_base_keeps_the_margin(reduced):
    robot = wbc.load_robot("deluca_mm")  # synchro base: the reduced form solves over its real inputs
    q0 = robot.neutral()
    wrist = robot.frame_pose(q0, "wrist_center")[:3, 3]
    sphere = wbc.Sphere(wrist + (0.3, 0.0, 0.0), 0.08)  # ahead of the wrist, on the way to its target
    reach = wbc.PositionTask("wrist_center", cost=1.0, gain=0.3, max_speed=0.5)
    reach.set_target(wrist + (0.6, 0.0, 0.0))
    tasks = [reach, wbc.PostureTask(cost=1e-3, gain=0.05), wbc.SteeringTask(cost=1e-2, gain=1.0, speed_scale=0.5)]
    constraints = [*LIMITS, wbc.NonholonomicBase(), wbc.CollisionAvoidance([sphere])]
    controller = wbc.Controller(robot, tasks, constraints, reduced=reduced)
    oracle, excluded = Oracle(robot, [sphere]), _excluded(robot)
    _, closest, _ = _run(controller, q0, 400, oracle, excluded)
    assert closest.min() >= MIN_DISTANCE - TOLERANCE
    unguarded = wbc.Controller(robot, tasks, constraints[:-1], reduced=reduced)
    _, through, _ = _run(unguarded, q0, 400, oracle, excluded)
    assert through.min() < 0.0


def test_rows_written_into_a_strided_block_are_the_same():
    """A controller's G block that is not C-contiguous gets the same rows (through a buffer)."""
    sphere = wbc.Sphere(EE + (0.1, 0.0, 0.0), 0.05)
    data = wbc.CollisionAvoidance([sphere]).bind(YOUBOT)
    n, nv = data.n_inequalities, YOUBOT.nv
    kin = Kinematics(YOUBOT)
    kin.update(NEUTRAL)
    blocks = []
    for G in (np.zeros((n, nv)), np.zeros((n, 2 * nv))[:, ::2]):
        rows = ConstraintRows(np.zeros(nv), np.zeros(nv), G, np.zeros(n), np.zeros((0, nv)), np.zeros(0))
        data.compute(kin, 0.01, rows)
        blocks.append((G.copy(), rows.h.copy()))
    np.testing.assert_array_equal(blocks[0][0], blocks[1][0])
    np.testing.assert_array_equal(blocks[0][1], blocks[1][1])
    assert np.any(blocks[0][0] != 0.0)


# ------------------------------------------------------------- detection against braking
@pytest.mark.parametrize("make, min_distance", [
    (lambda detection: wbc.CollisionAvoidance([wbc.Sphere([2.0, 0.0, 0.1], 0.05)], self_collision=False,
                                              min_distance=0.02, detection_distance=detection), 0.02),
    (lambda detection: wbc.BaseFootprintAvoidance([[-0.29, -0.19], [0.29, -0.19], [0.29, 0.19], [-0.29, 0.19]],
                                                  points=[[2.0, 0.0]], min_distance=0.05,
                                                  detection_distance=detection), 0.05),
])
def test_a_detection_shorter_than_the_platforms_braking_distance_warns(make, min_distance):
    """docs/acceleration.md: under AccelerationLimits a pair found closer than the braking distance
    cannot be braked for. The platform's stop from its top speed s along an axis at a_d, half the
    acceleration bound (0.8 m/s^2 on every coordinate here, below what the wheels' limits allow
    the platform: 1 m/s^2), written out: s^2 / (2 a_d) = 0.8 m for the youBot's 0.8 m/s. A
    detection leaving less than that before min_distance warns naming the fix; one leaving more,
    or no acceleration bounds, builds silently."""
    speed, rate = YOUBOT.base.max_linear_speed, 0.5 * 0.8
    assert speed == 0.8
    stop = speed ** 2 / (2 * rate)
    short, enough = min_distance + stop - 0.01, min_distance + stop + 0.01

    def build(item, bounds):
        return wbc.Controller(YOUBOT, [wbc.PostureTask(1.0)], [wbc.JointVelocityLimits(), item, *bounds])

    with pytest.warns(wbc.ConfigurationWarning, match=rf"need {stop:.3g} m to stop .* detection_distance >= "
                                                      rf"{stop + min_distance:.3g} m"):
        build(make(short), [wbc.AccelerationLimits(0.8)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        build(make(enough), [wbc.AccelerationLimits(0.8)])
        build(make(short), [])


@pytest.mark.parametrize("case", ["wall", "crate"])
def test_a_turning_platform_does_not_chatter_into_a_wall_or_a_crate(case):
    """The platform (a box) driven at 0.4 m/s toward a wall or a small yawed crate while it turns
    at ~0.9 rad/s: its closest feature jumps between its vertices (the wall) or between the crate's
    vertical edges (the crate) as it turns. With the witness row alone the feature about to become
    the closest had no row and came in unchecked: one tick 3.5 mm into the margin at the wall
    (16.55 mm kept of 20), 1.15 mm at the crate (18.86 mm; found by a fuzz of random planes and
    boxes). With rows for a box's vertices and edges (:func:`wbc.collision.kernels.corner_rows`)
    the margin holds on every tick, every tick optimal."""
    if case == "wall":
        obstacle = wbc.Plane((0.8917, -0.4527, 1.25e-4), -0.5551)
        heading, yaw_rate = np.array([-0.8917, 0.4527]), 0.909
    else:
        pose, angle = np.eye(4), 1.9846
        pose[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
        pose[:3, 3] = (-0.66425, -0.01143, -0.04664)
        obstacle = wbc.Box(pose, (0.15945, 0.07635, 0.17948))
        heading, yaw_rate = np.array([-0.99985, -0.01721]), 0.870
    oracle, excluded = Oracle(YOUBOT, [obstacle]), _excluded(YOUBOT)
    drive = wbc.BaseVelocityTask(cost=1.0)
    controller = wbc.Controller(YOUBOT, [drive, wbc.PostureTask(cost=1e-2, gain=0.3)],
                                [*LIMITS, wbc.CollisionAvoidance([obstacle], min_distance=MIN_DISTANCE)])
    q, closest = NEUTRAL.copy(), []
    world = 0.4 * heading / np.linalg.norm(heading)
    for _ in range(300):
        c, s = np.cos(q[2]), np.sin(q[2])
        drive.set_target((c * world[0] + s * world[1], -s * world[0] + c * world[1], yaw_rate))  # base frame
        v = controller.step(q)
        assert controller.last.success
        q = YOUBOT.integrate(q, v, 0.01)
        closest.append(min(d for key, d in oracle.distances(q).items() if key not in excluded and "obstacle0" in key))
    assert min(closest) < MIN_DISTANCE + 1e-3  # it drove up to the margin
    assert min(closest) >= MIN_DISTANCE - 5e-4
