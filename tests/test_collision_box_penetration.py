"""Overlapping boxes: the compiled signed distance (separating-axis theorem) against coal's."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest

from wbc import Box
from wbc.collision import kernels, layout

IDENTITY = np.array([[1.0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]])


def measure(boxes):
    """The compiled (d, w_a, w_b, n) of two boxes."""
    table = np.array([box.row() for box in boxes])
    world = np.zeros((2, kernels.POSE_COLUMNS))
    kernels.world_poses(table, IDENTITY, world)
    out = np.zeros(10)
    kernels.distance_of(table, world, 0, 1, out, np.zeros(layout.SCRATCH))
    return out


def coal_distance(boxes):
    """coal's signed distance (negative: penetration depth, EPA)."""
    request = coal.DistanceRequest()
    request.gjk_tolerance = 1e-12
    request.enable_signed_distance = True
    shapes = [(coal.Box(*box.size), coal.Transform3s(box.pose[:3, :3], box.pose[:3, 3])) for box in boxes]
    return coal.distance(*shapes[0], *shapes[1], request, coal.DistanceResult())


def random_boxes(rng, spread):
    boxes = []
    for _ in range(2):
        pose = np.eye(4)
        pose[:3, :3] = pin.utils.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3))
        pose[:3, 3] = rng.uniform(-spread, spread, 3)
        boxes.append(Box(pose, rng.uniform(0.05, 0.6, 3)))
    return boxes


def inside(box, point, tol=1e-9):
    local = box.pose[:3, :3].T @ (point - box.pose[:3, 3])
    return bool(np.all(np.abs(local) <= np.asarray(box.size) / 2 + tol))


@pytest.mark.parametrize("spread", [0.05, 0.3])  # deep, and shallow to deep overlaps
def test_depth_witnesses_and_normal_agree_with_coal(spread):
    """Random orientations and sizes: d = coal's signed distance (to 1e-8), ``w_b - w_a = d n``,
    |n| = 1, each witness inside its box's closure, and n points from a to b: moving b by
    eps n raises coal's d by eps to first order."""
    rng = np.random.default_rng(5)
    overlapping = 0
    for _ in range(300):
        boxes = random_boxes(rng, spread)
        expected = coal_distance(boxes)
        if expected > -1e-6:
            continue
        overlapping += 1
        out = measure(boxes)
        d, w_a, w_b, n = out[0], out[1:4], out[4:7], out[7:10]
        assert d == pytest.approx(expected, abs=1e-8)
        np.testing.assert_allclose(w_b - w_a, d * n, atol=1e-12)
        assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-12)
        assert inside(boxes[1], w_b) or inside(boxes[0], w_a)  # the deepest point is on its box
        eps = 1e-7
        moved = boxes[1].pose.copy()
        moved[:3, 3] += eps * n
        assert (coal_distance([boxes[0], Box(moved, boxes[1].size)]) - expected) / eps == pytest.approx(1.0, abs=1e-3)
    assert overlapping > 100


def test_edge_edge_and_face_face_overlaps():
    """Two crossed bars (the deepest contact edge against edge) and two aligned boxes (face
    against face): the depths by hand, both witnesses on their boxes."""
    a = Box(np.eye(4), (0.2, 2.0, 0.2))
    pose = np.eye(4)
    pose[:3, :3] = pin.utils.rpyToMatrix(0.0, 0.0, np.pi / 2) @ pin.utils.rpyToMatrix(np.pi / 4, 0.0, 0.0)
    pose[:3, 3] = (0.0, 0.0, 0.1 + 0.1 * np.sqrt(2) - 0.03)  # the bar's edge 3 cm into a's top face
    b = Box(pose, (2.0, 0.2, 0.2))
    out = measure([a, b])
    assert out[0] == pytest.approx(coal_distance([a, b]), abs=1e-9)
    assert out[0] == pytest.approx(-0.03, abs=1e-12)
    assert inside(a, out[1:4]) and inside(b, out[4:7])
    shifted = np.eye(4)
    shifted[:3, 3] = (0.05, 0.0, 0.25)
    out = measure([Box(np.eye(4), (0.4, 0.4, 0.4)), Box(shifted, (0.2, 0.2, 0.2))])
    assert out[0] == pytest.approx(-0.05, abs=1e-12)
    np.testing.assert_allclose(out[7:10], (0.0, 0.0, 1.0), atol=1e-12)
    np.testing.assert_allclose(out[4:7], (0.05, 0.0, 0.15), atol=1e-12)  # the middle of b's deepest face


def test_edge_axes_measure_an_edge_edge_overlap():
    """Two boxes whose smallest overlap is along an edge cross product (found on random pairs):
    without the 9 edge axes the depth would be larger than coal's."""
    rng = np.random.default_rng(11)
    found = 0
    for _ in range(400):
        boxes = random_boxes(rng, 0.3)
        expected = coal_distance(boxes)
        out = measure(boxes)
        if expected < -1e-6:
            axes = [boxes[k].pose[:3, i] for k in range(2) for i in range(3)]
            if min(abs(np.dot(out[7:10], axis)) for axis in axes) < 0.999:
                found += 1  # an edge-edge axis
                assert out[0] == pytest.approx(expected, abs=1e-8)
    assert found > 5


def test_continuous_at_touching():
    """Through contact (b moved along a fixed direction), d from the separated path and from the
    overlap path agree near 0 and match the motion to 1e-9."""
    rng = np.random.default_rng(23)
    for _ in range(20):
        a, b = random_boxes(rng, 0.0)
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        lo, hi = 0.0, 2.0  # bisect the touching offset on the compiled d
        for _ in range(80):
            mid = (lo + hi) / 2
            pose = b.pose.copy()
            pose[:3, 3] += mid * direction
            lo, hi = (mid, hi) if measure([a, Box(pose, b.size)])[0] <= 0.0 else (lo, mid)
        values = []
        for step in (-1e-7, 1e-7):
            pose = b.pose.copy()
            pose[:3, 3] += (lo + step) * direction
            values.append(measure([a, Box(pose, b.size)])[0])
        assert values[0] < 0.0 < values[1]
        assert abs(values[0]) < 1e-7 + 1e-9 and abs(values[1]) < 1e-7 + 1e-9
        normal = measure([a, Box(pose, b.size)])[7:10]
        assert values[1] - values[0] == pytest.approx(2e-7 * abs(direction @ normal), abs=1e-9)


def test_row_is_the_gradient_of_coals_distance():
    """The row convention normal . (v_b(w_b) - v_a(w_a)) for a rigid motion of b (linear v,
    angular w about the world origin) against central differences of coal's signed distance."""
    rng = np.random.default_rng(29)
    checked = 0
    for _ in range(200):
        boxes = random_boxes(rng, 0.2)
        if coal_distance(boxes) > -1e-3:
            continue
        out = measure(boxes)
        w_b, n = out[4:7], out[7:10]
        for _ in range(3):
            v, w = rng.normal(size=3), rng.normal(size=3)
            row = n @ (v + np.cross(w, w_b))
            h = 1e-6
            values = []
            for sign in (1.0, -1.0):
                motion = pin.exp6(pin.Motion(sign * h * v, sign * h * w)).homogeneous
                moved = motion @ boxes[1].pose
                values.append(coal_distance([boxes[0], Box(moved, boxes[1].size)]))
            assert (values[0] - values[1]) / (2 * h) == pytest.approx(row, abs=1e-4 * (1 + abs(row)))
        checked += 1
    assert checked > 20


def test_robot_rows_match_finite_differences_of_coal():
    """The youBot's platform box overlapping a box obstacle, at random configurations near the
    neutral one: the pair's row against central differences of coal's signed distance (the
    Oracle of test_collision_distances, the URDF's box) along random velocities."""
    import wbc
    from test_collision_distances import Oracle
    from wbc.constraints.constraint import ConstraintRows
    from wbc.model.kinematics import Kinematics

    robot = wbc.load_robot("youbot")
    rng = np.random.default_rng(31)
    geometry = wbc.collision.RobotGeometry(robot)
    platform = next(i for i, link in enumerate(geometry.links) if geometry.table[i, 0] == 3)
    link = geometry.links[platform]
    pose = np.eye(4)
    pose[:3, :3] = pin.utils.rpyToMatrix(0.1, 0.2, 0.3)
    pose[:3, 3] = robot.frame_pose(robot.neutral(), link)[:3, 3] + (0.25, 0.05, 0.0)
    box = wbc.Box(pose, (0.2, 0.2, 0.2))
    data = wbc.CollisionAvoidance([box], self_collision=False).bind(robot)
    oracle, kin = Oracle(robot, [box]), Kinematics(robot)
    n, nv = data.n_inequalities, robot.nv
    rows = ConstraintRows(np.zeros(nv), np.zeros(nv), np.zeros((n, nv)), np.zeros(n), np.zeros((0, nv)), np.zeros(0))
    key = frozenset((link, "obstacle0"))
    for _ in range(5):
        q = pin.integrate(robot.model, robot.neutral(), 0.05 * rng.normal(size=nv))
        kin.update(q)
        data.compute(kin, 0.01, rows)
        entry = data.active_labels().index(f"{link}↔box0")
        distance = data.pairs.distance[entry]
        assert distance == pytest.approx(oracle.distances(q)[key], abs=1e-8)
        assert distance < 0.0
        for _ in range(3):
            v, h = rng.normal(size=nv), 1e-6
            difference = (oracle.distances(pin.integrate(robot.model, q, h * v))[key]
                          - oracle.distances(pin.integrate(robot.model, q, -h * v))[key]) / (2 * h)
            assert data.pairs.rows[entry] @ v == pytest.approx(difference, abs=1e-5)
