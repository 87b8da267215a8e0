"""The coal hand-off: shapes without a compiled distance (``layout.COAL``: a URDF ``<cylinder>``
that is not a capsule) are left by the compiled entry to coal in Python
(:meth:`wbc.collision.Distances.finish_with_coal`), next to compiled pairs (a box link against
sphere, capsule and box obstacles). Checked on a small robot written here: distances and witness
points against coal called directly on the URDF's shapes (Pinocchio's placements, not the
kernels'), the rows against finite differences of those distances, and CollisionAvoidance with
such pairs: its rows stay in Python (no op in the tick program) and keep the margin in a closed
loop that drives the cylinders into a box."""

import coal
import numpy as np
import pinocchio as pin
import pytest

import wbc
from test_collision_distances import _coal_obstacle
from wbc.collision import Distances, layout
from wbc.collision.avoidance import CollisionAvoidanceData, compiled_pairs_only

#: a cart (a vertical cylinder: coal) on a rail along x, a boom (a box: compiled) on a shoulder
#: about z, a hand (a horizontal cylinder: coal) on an elbow about y
URDF = """<robot name="coal_arm">
  <link name="world"/>
  <link name="cart">
    <collision><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.1" length="0.2"/></geometry></collision>
  </link>
  <link name="boom">
    <collision><origin xyz="0.2 0 0"/><geometry><box size="0.4 0.06 0.06"/></geometry></collision>
  </link>
  <link name="hand">
    <collision><origin xyz="0.075 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="0.03" length="0.15"/></geometry></collision>
  </link>
  <joint name="rail" type="prismatic"><parent link="world"/><child link="cart"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="0.5"/></joint>
  <joint name="shoulder" type="revolute"><parent link="cart"/><child link="boom"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="boom"/><child link="hand"/><origin xyz="0.4 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" effort="1" velocity="1"/></joint>
</robot>"""
MIN_DISTANCE = 0.02
TOLERANCE = 2e-3  #: a tick's second-order term at these speeds, as in test_collision_avoidance
FAR = 100.0  #: a detection distance that keeps every pair


def _obstacles():
    pose = np.eye(4)
    pose[:3, :3] = pin.utils.rpyToMatrix(0.2, -0.3, 0.5)
    pose[:3, 3] = (0.9, 0.05, 0.15)
    return [wbc.Sphere((0.6, 0.35, 0.35), 0.07), wbc.Capsule((0.5, -0.4, 0.0), (0.7, -0.35, 0.6), 0.05),
            wbc.Box(pose, (0.2, 0.3, 0.25))]


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    path = tmp_path_factory.mktemp("coal_arm") / "coal_arm.urdf"
    path.write_text(URDF)
    return wbc.load_robot(path)


class CoalPairs:
    """Per pair of links (or link and obstacle ``obstacle<k>``), coal's signed distance and witness
    points on the URDF's raw shapes placed by Pinocchio (``updateGeometryPlacements``), each shape
    pair measured with its own coal.distance call (GJK to 1e-12)."""

    def __init__(self, robot, obstacles):
        self.robot, self.data = robot, robot.model.createData()
        self.geometry = pin.buildGeomFromUrdf(robot.model, str(robot.source), pin.GeometryType.COLLISION)
        self.geometry_data = pin.GeometryData(self.geometry)
        self.links = [robot.model.frames[obj.parentFrame].name for obj in self.geometry.geometryObjects]
        self.obstacles = [(f"obstacle{k}", *_coal_obstacle(obstacle)) for k, obstacle in enumerate(obstacles)]
        self.request = coal.DistanceRequest()
        self.request.gjk_tolerance, self.request.gjk_max_iterations = 1e-12, 1000

    def _measure(self, shape_a, pose_a, shape_b, pose_b):
        result = coal.DistanceResult()
        coal.distance(shape_a, coal.Transform3s(pose_a.rotation, pose_a.translation), shape_b,
                      coal.Transform3s(pose_b.rotation, pose_b.translation), self.request, result)
        return result.min_distance, result.getNearestPoint1().copy(), result.getNearestPoint2().copy()

    def pairs(self, q):
        """{(name_a, name_b): (d, w_a, w_b)}, both orders, for every pair of distinct links and
        every link against every obstacle."""
        pin.updateGeometryPlacements(self.robot.model, self.data, self.geometry, self.geometry_data, q)
        shapes = [(name, obj.geometry, pose) for name, obj, pose in
                  zip(self.links, self.geometry.geometryObjects, self.geometry_data.oMg, strict=True)]
        shapes += self.obstacles
        found = {}
        for i, (name_a, shape_a, pose_a) in enumerate(shapes):
            for name_b, shape_b, pose_b in shapes[i + 1:]:
                if name_a == name_b or (name_a.startswith("obstacle") and name_b.startswith("obstacle")):
                    continue
                d, w_a, w_b = self._measure(shape_a, pose_a, shape_b, pose_b)
                if d < found.get((name_a, name_b), (np.inf,))[0]:
                    found[name_a, name_b], found[name_b, name_a] = (d, w_a, w_b), (d, w_b, w_a)
        return found


def _pair_names(distances):
    """(name_a, name_b) of each candidate pair, in the oracle's names (obstacles ``obstacle<k>``)."""
    names = list(distances.geometry.links) + [f"obstacle{k}" for k in range(len(distances.obstacles))]
    return [(names[a], names[b]) for a, b, _ in distances.pairs.tolist()]


def _on_coal(distances, pair):
    return layout.COAL in distances.table[distances.pairs[pair, :2], layout.KIND]


def test_the_robot_mixes_coal_and_compiled_pairs(robot):
    distances = Distances(robot, _obstacles(), detection_distance=FAR)
    kinds = {link: distances.table[row, layout.KIND] for row, link in enumerate(distances.geometry.links)}
    assert kinds == {"cart": layout.COAL, "boom": layout.BOX, "hand": layout.COAL}
    on_coal = [_on_coal(distances, pair) for pair in range(distances.pairs.shape[0])]
    assert any(on_coal) and not all(on_coal)
    assert not compiled_pairs_only(distances)
    assert {"cart↔hand"} <= set(distances.labels)  # a self pair of two coal shapes


def test_distances_and_witnesses_agree_with_coal(robot):
    """Every candidate pair gets an entry (FAR); coal's pairs (the hand-off) have coal's distance,
    penetration included, the compiled ones where separated; for separated pairs (a unique witness
    pair: the random configurations are generic) the witness points are coal's too, and always
    ``w_b - w_a = d n`` with a unit normal. Tolerances: GJK to 1e-9 in the hand-off puts the points
    on a cylinder ~1e-5 off (measured 2.4e-5 at most over 200 configurations); the compiled
    distances are exact. An overlapping compiled pair (a boom through the capsule) is measured by
    the segment's deepest point, not coal's translation depth: as deep or shallower, < 0."""
    obstacles = _obstacles()
    distances = Distances(robot, obstacles, detection_distance=FAR)
    oracle, out, names = CoalPairs(robot, obstacles), distances.buffers(), _pair_names(distances)
    rng = np.random.default_rng(3)
    checked = {True: 0, False: 0}
    for _ in range(25):
        q = rng.uniform(robot.lower, robot.upper) * (0.35, 0.9, 0.9)
        count = distances.compute(q, out)
        expected = oracle.pairs(q)
        assert sorted(out.pair[:count].tolist()) == list(range(distances.pairs.shape[0]))  # every pair, once
        for slot in range(count):
            pair = int(out.pair[slot])
            d, w_a, w_b = expected[names[pair]]
            coal_pair, label = _on_coal(distances, pair), distances.labels[pair]
            np.testing.assert_allclose(np.linalg.norm(out.normal[slot]), 1.0, atol=1e-9)
            np.testing.assert_allclose(out.witness_b[slot] - out.witness_a[slot], out.distance[slot] * out.normal[slot],
                                       atol=1e-7)
            if coal_pair or d > 0.0:
                assert out.distance[slot] == pytest.approx(d, abs=1e-8), label
            else:
                assert d - 1e-9 <= out.distance[slot] <= 0.0, label
            if d > 1e-3:
                tolerance = 1e-4 if coal_pair else 1e-9
                np.testing.assert_allclose(out.witness_a[slot], w_a, atol=tolerance, err_msg=label)
                np.testing.assert_allclose(out.witness_b[slot], w_b, atol=tolerance, err_msg=label)
                checked[coal_pair] += 1
    assert checked[True] > 50 and checked[False] > 50


def test_rows_match_finite_differences_of_coal(robot):
    """``rows[i] @ v`` is the rate of coal's distance (the oracle's, central differences) along v,
    for every separated pair, coal's and compiled."""
    obstacles = _obstacles()
    distances = Distances(robot, obstacles, detection_distance=FAR)
    oracle, out, names = CoalPairs(robot, obstacles), distances.buffers(), _pair_names(distances)
    rng, eps = np.random.default_rng(8), 1e-6
    checked = {True: 0, False: 0}
    for _ in range(15):
        q = rng.uniform(robot.lower, robot.upper) * (0.35, 0.9, 0.9)
        count = distances.compute(q, out)
        v = rng.standard_normal(robot.nv)
        plus, minus = oracle.pairs(robot.integrate(q, v, eps)), oracle.pairs(robot.integrate(q, -v, eps))
        for slot in range(count):
            if out.distance[slot] < 1e-3:
                continue  # in contact: no unique witness pair
            pair = int(out.pair[slot])
            rate = (plus[names[pair]][0] - minus[names[pair]][0]) / (2 * eps)
            coal_pair = _on_coal(distances, pair)
            # coal's witness points on a cylinder (GJK to 1e-9) give the row to ~1e-5 relative
            tolerance = 1e-4 * (1 + abs(rate)) if coal_pair else 1e-6 * (1 + abs(rate))
            assert out.rows[slot] @ v == pytest.approx(rate, abs=tolerance), distances.labels[pair]
            checked[coal_pair] += 1
    assert checked[True] > 30 and checked[False] > 30


def _controller(robot, target, avoidance):
    posture = wbc.PostureTask(cost=1.0, gain=0.3, target=target)
    constraints = [wbc.JointPositionLimits(), wbc.JointVelocityLimits()]
    return wbc.Controller(robot, [posture], constraints + ([avoidance] if avoidance is not None else []))


def test_the_rows_stay_in_python_and_keep_the_margin(robot, monkeypatch):
    """With coal pairs the constraint adds no op to the tick program (its add_ops declines: not
    compiled_pairs_only) and computes its rows in Python every tick; driving the cart into the
    box (the posture's target is past it, the elbow pitching the hand down onto it) keeps coal's
    smallest distance over the pairs >= MIN_DISTANCE - TOLERANCE every tick, and the cart ends at
    the margin; without the constraint the same run goes into the box."""
    box = _obstacles()[2]
    answers = []
    add_ops = CollisionAvoidanceData.add_ops

    def spy(self, program, kin, rows):
        answers.append(add_ops(self, program, kin, rows))
        return answers[-1]

    monkeypatch.setattr(CollisionAvoidanceData, "add_ops", spy)
    avoidance = wbc.CollisionAvoidance([box], min_distance=MIN_DISTANCE)
    target = np.array([1.2, 0.0, 0.6])
    controller = _controller(robot, target, avoidance)
    assert answers and not any(answers)  # asked (each time the program is built), declined
    data = controller.data(avoidance)
    assert not compiled_pairs_only(data.distances)
    assert any(item is data for item, _ in controller._python_constraints)
    oracle = CoalPairs(robot, [box])
    excluded = {frozenset((e.link_a, e.link_b)) for e in data.distances.geometry.excluded}

    covered = [names for names in _pair_names(data.distances) if frozenset(names) not in excluded]

    def closest(q):
        pairs = oracle.pairs(q)
        return {names: pairs[names][0] for names in covered}

    q, worst, binding = np.zeros(robot.nv), {}, set()
    for _ in range(250):
        v = controller.step(q)
        assert np.all(np.isfinite(v)) and controller.last.outcome is wbc.Outcome.OPTIMAL
        binding.update(label for label in controller.active_constraints(v) if "box0" in label)
        q = robot.integrate(q, v, 0.01)
        for names, d in closest(q).items():
            worst[names] = min(worst.get(names, np.inf), d)
    assert min(worst.values()) >= MIN_DISTANCE - TOLERANCE
    assert "CollisionAvoidance: cart↔box0" in binding  # a coal pair's row held the cart back
    assert worst["cart", "obstacle0"] < MIN_DISTANCE + 0.01  # the cart went up to the margin
    free = _controller(robot, target, None)
    q, unguarded = np.zeros(robot.nv), np.inf
    for _ in range(250):
        q = robot.integrate(q, free.step(q), 0.01)
        unguarded = min(unguarded, *closest(q).values())
    assert unguarded < 0.0  # unguarded, the same posture drives through the box
