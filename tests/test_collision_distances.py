"""Signed distances and gradient rows of wbc.collision.Distances, against independent oracles:
coal through Pinocchio's computeDistances on the URDF's raw <collision> shapes (the capsule
triples as written, obstacles as coal shapes built here), finite differences for the rows."""

import coal
import numpy as np
import pinocchio as pin
import pytest

import wbc
from wbc.collision import Box, Capsule, Distances, Plane, RobotGeometry, Sphere, layout

ROBOTS = ["youbot", "puma560", "scorbot_er4pc", "deluca_mm"]
FAR = 100.0  #: a detection distance that keeps every pair


def _obstacles():
    pose = np.eye(4)
    pose[:3, :3] = pin.utils.rpyToMatrix(0.3, -0.2, 0.7)
    pose[:3, 3] = (0.45, -0.2, 0.35)
    return [Sphere((0.5, 0.1, 0.4), 0.08), Box(pose, (0.2, 0.1, 0.3)),
            Capsule((0.3, 0.4, 0.1), (0.6, 0.3, 0.6), 0.05), Plane((0, 0, 1), -0.3)]


def _coal_obstacle(obstacle):
    """The obstacle as coal geometry and its world placement, from its public parameters."""
    if isinstance(obstacle, Sphere):
        return coal.Sphere(obstacle.radius), pin.SE3(np.eye(3), obstacle.center)
    if isinstance(obstacle, Box):
        pose = obstacle.pose
        return coal.Box(*obstacle.size), pin.SE3(pose[:3, :3], pose[:3, 3])
    if isinstance(obstacle, Capsule):
        p0, p1 = obstacle.points
        axis = (p1 - p0) / np.linalg.norm(p1 - p0)
        rotation = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), axis).matrix()
        return coal.Capsule(obstacle.radius, np.linalg.norm(p1 - p0)), pin.SE3(rotation, (p0 + p1) / 2)
    return coal.Halfspace(obstacle.normal, obstacle.offset), pin.SE3.Identity()


class Oracle:
    """Per pair of links (or link and obstacle), the smallest coal distance between the raw URDF
    shapes of the two (the distance to a union is the smallest of the distances to its parts)."""

    def __init__(self, robot, obstacles):
        self.robot = robot
        self.model = pin.buildGeomFromUrdf(robot.model, str(robot.source), pin.GeometryType.COLLISION)
        self.links = [robot.model.frames[obj.parentFrame].name for obj in self.model.geometryObjects]
        n_robot = self.model.ngeoms
        for index, obstacle in enumerate(obstacles):
            shape, placement = _coal_obstacle(obstacle)
            self.model.addGeometryObject(pin.GeometryObject(f"obstacle{index}", 0, 0, placement, shape))
            self.links.append(f"obstacle{index}")
        for a in range(self.model.ngeoms):
            for b in range(a + 1, self.model.ngeoms):
                if self.links[a] != self.links[b] and not (a >= n_robot and b >= n_robot):
                    self.model.addCollisionPair(pin.CollisionPair(a, b))
        self.data = pin.GeometryData(self.model)
        for request in self.data.distanceRequests:  # GJK converges from above: to ~1e-6 by default
            request.gjk_tolerance = 1e-12
            request.gjk_max_iterations = 1000
        self.robot_data = robot.model.createData()

    def distances(self, q):
        pin.computeDistances(self.robot.model, self.robot_data, self.model, self.data, q)
        result = {}
        for pair, found in zip(self.model.collisionPairs, self.data.distanceResults, strict=True):
            key = frozenset((self.links[pair.first], self.links[pair.second]))
            result[key] = min(result.get(key, np.inf), found.min_distance)
        return result


def _link_names(distances):
    geometry = distances.geometry
    return list(geometry.links) + [f"obstacle{k}" for k in range(len(distances.obstacles))]


def _by_links(distances, out):
    names, found = _link_names(distances), {}
    for slot in range(out.count):
        a, b, _ = distances.pairs[out.pair[slot]]
        key = frozenset((names[a], names[b]))
        found[key] = min(found.get(key, np.inf), out.distance[slot])
    return found


@pytest.mark.parametrize("name", ROBOTS)
def test_distances_agree_with_coal(name):
    robot = wbc.load_robot(name)
    obstacles = _obstacles()
    distances = Distances(robot, obstacles, detection_distance=FAR)
    oracle, out = Oracle(robot, obstacles), distances.buffers()
    rng = np.random.default_rng(7)
    compared = 0
    # a link pair with an excluded shape pair (PUMA: forearm and wrist touch always) is not comparable
    excluded = {frozenset((e.link_a, e.link_b)) for e in distances.geometry.excluded}
    for _ in range(40):
        q = robot.random_configuration(rng, base_range=0.3)
        distances.compute(q, out)
        expected = oracle.distances(q)
        for key, value in _by_links(distances, out).items():
            if key in excluded:
                continue
            if expected[key] > 1e-3:  # separated: coal's GJK distance is exact there
                assert value == pytest.approx(expected[key], abs=1e-6), (key, q)
                compared += 1
            else:  # in contact: both say so
                assert value < 1e-3 + 1e-6, (key, q)
    assert compared > 100


@pytest.mark.parametrize("name", ROBOTS)
def test_witness_points_and_normals_are_consistent(name):
    robot = wbc.load_robot(name)
    distances = Distances(robot, _obstacles(), detection_distance=FAR)
    out, rng = distances.buffers(), np.random.default_rng(3)
    for _ in range(20):
        distances.compute(robot.random_configuration(rng, base_range=0.3), out)
        n = out.count
        np.testing.assert_allclose(np.linalg.norm(out.normal[:n], axis=1), 1.0, atol=1e-9)
        np.testing.assert_allclose(out.witness_b[:n] - out.witness_a[:n], out.distance[:n, None] * out.normal[:n],
                                   atol=1e-7)


def _distance_of(distances, out, q, pair):
    distances.compute(q, out)
    slots = np.flatnonzero(out.pair[:out.count] == pair)
    return out.distance[slots[0]]


@pytest.mark.parametrize("name", ROBOTS)
def test_gradient_rows_match_finite_differences(name):
    robot = wbc.load_robot(name)
    distances = Distances(robot, _obstacles(), detection_distance=FAR)
    out, probe = distances.buffers(), distances.buffers()
    rng, eps, checked = np.random.default_rng(11), 1e-5, 0
    for _ in range(15):
        q = robot.random_configuration(rng, base_range=0.3)
        distances.compute(q, out)
        for slot in range(out.count):
            if out.distance[slot] < 1e-3:
                continue  # penetration: coal's path, and no unique witness pair
            pair, row = out.pair[slot], out.rows[slot].copy()
            v = rng.standard_normal(robot.nv)
            plus = _distance_of(distances, probe, robot.integrate(q, v, eps), pair)
            minus = _distance_of(distances, probe, robot.integrate(q, -v, eps), pair)
            expected = (plus - minus) / (2 * eps)
            kinds = {distances.table[shape, layout.KIND] for shape in distances.pairs[pair, :2]}
            # coal's GJK witness points on curved shapes (a cylinder) are good to ~1e-4
            on_coal = layout.COAL in kinds
            tolerance = 2e-4 * (1 + abs(expected)) if on_coal else 1e-6 * (1 + abs(expected))
            assert row @ v == pytest.approx(expected, abs=tolerance), distances.labels[pair]
            checked += 1
    assert checked > 50


def test_far_pairs_get_no_entry():
    robot = wbc.load_robot("youbot")
    far = Sphere((10.0, 0.0, 0.0), 0.1)
    distances = Distances(robot, [far], self_collision=False, detection_distance=0.3)
    out = distances.buffers()
    assert distances.compute(robot.neutral(), out) == 0
    far.center = (0.5, 0.0, 0.3)  # moved between calls: now close to the arm
    count = distances.compute(robot.neutral(), out)
    assert count > 0 and np.all(out.distance[:count] < 0.3)
    # every entry is a pair within 0.3 m, and every such pair has an entry (coal as the oracle)
    expected = {k: d for k, d in Oracle(robot, [far]).distances(robot.neutral()).items() if "obstacle0" in k}
    found = _by_links(distances, out)
    assert set(found) == {k for k, d in expected.items() if d < 0.3}


def test_self_collision_off_measures_obstacles_only():
    robot = wbc.load_robot("youbot")
    distances = Distances(robot, [Sphere((0.5, 0.0, 0.3), 0.1)], self_collision=False, detection_distance=FAR)
    out = distances.buffers()
    distances.compute(robot.neutral(), out)
    assert all("sphere0" in distances.labels[p] for p in out.pair[:out.count])
    assert out.count == RobotGeometry(robot).size  # every youBot shape moves (the base is a joint)


def test_a_full_buffer_keeps_the_closest_pairs():
    robot = wbc.load_robot("youbot")
    obstacles = _obstacles()
    everything = Distances(robot, obstacles, detection_distance=FAR)
    few = Distances(robot, obstacles, detection_distance=FAR, capacity=5)
    all_out, few_out = everything.buffers(), few.buffers()
    q = robot.neutral()
    everything.compute(q, all_out)
    assert few.compute(q, few_out) == 5
    np.testing.assert_allclose(np.sort(few_out.distance[:5]), np.sort(all_out.distance[:all_out.count])[:5])


def test_bad_input_is_refused():
    robot = wbc.load_robot("youbot")
    with pytest.raises(wbc.InvalidInputError, match="detection_distance"):
        Distances(robot, [], detection_distance=-1.0)
    with pytest.raises(wbc.InvalidInputError, match="capacity"):
        Distances(robot, [], capacity=0)
    with pytest.raises(wbc.InvalidInputError, match="obstacles"):
        Distances(robot, ["sphere"])
    distances = Distances(robot, [], capacity=3)
    with pytest.raises(wbc.InvalidInputError, match="buffers"):
        distances.compute(robot.neutral(), Distances(robot, [], capacity=4).buffers())


def test_box_box_distances_agree_with_coal():
    """Random box pairs, a third axis-aligned: the compiled distance (the smallest of 24 edge-to-box
    distances, best first) where they are apart, the separating-axis depth where they overlap
    (tests/test_collision_box_penetration.py), both coal's."""
    from wbc.collision import kernels

    rng = np.random.default_rng(17)
    out, scratch, separated, overlapping = np.zeros(10), np.zeros(layout.SCRATCH), 0, 0
    for sample in range(300):
        boxes = []
        for _ in range(2):
            pose = np.eye(4)
            if sample % 3:  # else axis-aligned on a 5 cm grid: faces parallel, many edges tie
                pose[:3, :3] = pin.utils.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3))
            pose[:3, 3] = rng.uniform(-0.3, 0.3, 3) if sample % 3 else np.round(rng.uniform(-0.3, 0.3, 3) * 20) / 20
            boxes.append(Box(pose, rng.uniform(0.05, 0.4, 3)))
        table = np.array([box.row() for box in boxes])
        world = np.zeros((2, kernels.POSE_COLUMNS))
        kernels.world_poses(table, np.array([[1.0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]]), world)
        found = kernels.distance_of(table, world, 0, 1, out, scratch)
        result = coal.DistanceResult()
        request = coal.DistanceRequest()
        request.gjk_tolerance = 1e-12
        shapes = [coal.Box(*box.size) for box in boxes]
        transforms = [coal.Transform3s(box.pose[:3, :3], box.pose[:3, 3]) for box in boxes]
        coal.distance(shapes[0], transforms[0], shapes[1], transforms[1], request, result)
        if result.min_distance > 1e-9:
            assert found == pytest.approx(result.min_distance, abs=1e-7)
            np.testing.assert_allclose(out[4:7] - out[1:4], found * out[7:10], atol=1e-9)
            separated += 1
        elif result.min_distance < -1e-9:
            assert found == pytest.approx(result.min_distance, abs=1e-7)
            overlapping += 1
    assert separated > 50 and overlapping > 20
