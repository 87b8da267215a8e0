"""Robot collision geometry (wbc.collision.geometry): capsules read back from URDF triples, the
self-collision pairs (adjacent, always-in-contact and SRDF pairs excluded), clear errors."""

import re

import coal
import numpy as np
import pinocchio as pin
import pytest

import wbc
from wbc.collision import RobotGeometry, layout

ARM = """<?xml version="1.0"?>
<robot name="arm">
  <link name="world"/>
  <link name="base"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <joint name="fix" type="fixed"><parent link="world"/><child link="base"/></joint>
  <link name="upper">
    <collision><origin xyz="0.15 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="0.03" length="0.3"/></geometry></collision>
    <collision><origin xyz="0 0 0"/><geometry><sphere radius="0.03"/></geometry></collision>
    <collision><origin xyz="0.3 0 0"/><geometry><sphere radius="0.03"/></geometry></collision>
  </link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.2"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
  <link name="lower">
    <collision><origin xyz="0.15 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="0.02" length="0.3"/></geometry></collision>
    <collision><origin xyz="0 0 0"/><geometry><sphere radius="0.025"/></geometry></collision>
    <collision><origin xyz="0.3 0 0"/><geometry><sphere radius="0.02"/></geometry></collision>
    {extra}
  </link>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/><origin xyz="0.3 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
  <link name="hand"><collision><origin xyz="0.05 0 0"/><geometry><sphere radius="0.03"/></geometry></collision></link>
  <joint name="wrist" type="revolute"><parent link="lower"/><child link="hand"/><origin xyz="0.3 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
</robot>
"""

#: a sphere on "lower" that reaches the base from everywhere the elbow can go (0.5 m > 0.2 + 0.3)
BIG_SPHERE = '<collision><origin xyz="0 0 0"/><geometry><sphere radius="0.6"/></geometry></collision>'


def _arm(tmp_path, extra=""):
    path = tmp_path / "arm.urdf"
    path.write_text(ARM.format(extra=extra))
    return wbc.load_robot(path)


def _pairs(geometry):
    return {frozenset((geometry.links[a], geometry.links[b])) for a, b in geometry.pairs}


def test_capsule_triples_become_capsules(tmp_path):
    geometry = RobotGeometry(_arm(tmp_path))
    kinds = {link: geometry.table[k, layout.KIND] for k, link in enumerate(geometry.links)}
    assert geometry.size == 6  # base box, upper capsule, lower cylinder + 2 spheres (radii differ), hand sphere
    assert kinds["upper"] == layout.CAPSULE
    upper = geometry.links.index("upper")
    shape = geometry.model.geometryObjects[upper].geometry
    assert isinstance(shape, coal.Capsule) and shape.radius == pytest.approx(0.03)
    assert shape.halfLength == pytest.approx(0.15)
    # the lower link's spheres do not match the cylinder's radius: kept as they are (the cylinder for coal)
    assert sorted(geometry.table[k, layout.KIND] for k, link in enumerate(geometry.links) if link == "lower") == [
        layout.SPHERE, layout.SPHERE, layout.COAL]


def test_adjacent_pairs_are_excluded(tmp_path):
    geometry = RobotGeometry(_arm(tmp_path))
    pairs = _pairs(geometry)
    assert frozenset(("base", "upper")) not in pairs and frozenset(("upper", "lower")) not in pairs
    assert frozenset(("lower", "hand")) not in pairs
    assert frozenset(("base", "lower")) in pairs and frozenset(("upper", "hand")) in pairs
    assert frozenset(("base", "hand")) in pairs
    reasons = {frozenset((e.link_a, e.link_b)): e.reason for e in geometry.excluded}
    assert reasons[frozenset(("base", "upper"))] == "adjacent"


def test_pairs_always_in_contact_are_excluded(tmp_path):
    geometry = RobotGeometry(_arm(tmp_path, BIG_SPHERE))
    big = next(k for k in range(geometry.size) if geometry.table[k, layout.RADIUS] == pytest.approx(0.6))
    base = geometry.links.index("base")
    assert (base, big) not in geometry.pairs and (big, base) not in geometry.pairs
    assert any(e.reason == "always in contact" and {e.link_a, e.link_b} == {"base", "lower"} for e in geometry.excluded)
    # the lower link's other shapes against the base stay pairs: not always in contact
    assert any({a, b} == {base, k} for a, b in geometry.pairs for k in range(geometry.size)
               if geometry.links[k] == "lower" and k != big)


def test_always_in_contact_agrees_with_coal_on_fresh_samples(tmp_path):
    """Every kept pair is free somewhere: coal finds it free at one of 2000 new samples."""
    robot = _arm(tmp_path, BIG_SPHERE)
    geometry = RobotGeometry(robot)
    model = pin.GeometryModel()
    for obj in geometry.model.geometryObjects:
        model.addGeometryObject(obj)
    for a, b in geometry.pairs:
        model.addCollisionPair(pin.CollisionPair(a, b))
    data, robot_data = pin.GeometryData(model), robot.model.createData()
    free = np.zeros(len(geometry.pairs), dtype=bool)
    rng = np.random.default_rng(123)
    for _ in range(2000):
        pin.computeCollisions(robot.model, robot_data, model, data, robot.random_configuration(rng), False)
        free |= [not result.isCollision() for result in data.collisionResults]
    assert free.all()


def test_srdf_disables_pairs(tmp_path):
    robot = _arm(tmp_path)
    srdf = tmp_path / "arm.srdf"
    srdf.write_text('<robot name="arm"><disable_collisions link1="base" link2="hand" reason="Never"/></robot>')
    geometry = RobotGeometry(robot, srdf=srdf)
    assert frozenset(("base", "hand")) not in _pairs(geometry)
    assert any(e.reason == "SRDF" and {e.link_a, e.link_b} == {"base", "hand"} for e in geometry.excluded)
    srdf.write_text('<robot name="arm"><disable_collisions link1="base" link2="claw"/></robot>')
    with pytest.raises(wbc.ModelError, match="claw"):
        RobotGeometry(robot, srdf=srdf)
    with pytest.raises(wbc.ModelError, match="cannot read the SRDF"):
        RobotGeometry(robot, srdf=tmp_path / "missing.srdf")


def test_a_urdf_without_collision_elements_is_refused_with_the_fix(tmp_path):
    path = tmp_path / "bare.urdf"
    path.write_text(re.sub(r"<collision>.*?</collision>", "", ARM.format(extra=""), flags=re.S))
    with pytest.raises(wbc.ModelError, match="no collision geometry.*add <collision> elements"):
        RobotGeometry(wbc.load_robot(path))


def test_samples_must_be_a_positive_int():
    robot = wbc.load_robot("scorbot_er4pc")
    for samples in (0, 1.5, True):
        with pytest.raises(wbc.InvalidInputError, match="samples"):
            RobotGeometry(robot, samples=samples)


@pytest.mark.parametrize("name", ["youbot", "puma560", "scorbot_er4pc", "deluca_mm"])
def test_shipped_models_have_collision_geometry(name):
    """Every moving link with a <collision> element takes part in some pair or is adjacent-only."""
    robot = wbc.load_robot(name)
    geometry = RobotGeometry(robot)
    assert geometry.size >= 4
    assert geometry.pairs
    for a, b in geometry.pairs:
        joint_a, joint_b = (geometry.model.geometryObjects[k].parentJoint for k in (a, b))
        assert joint_a != joint_b
        assert robot.model.parents[joint_a] != joint_b and robot.model.parents[joint_b] != joint_a


def test_youbot_platform_and_arm_pairs():
    geometry = RobotGeometry(wbc.load_robot("youbot"))
    pairs = _pairs(geometry)
    assert frozenset(("base_link", "arm_link_2")) in pairs  # the arm folded onto its platform
    assert frozenset(("base_link", "arm_link_1")) not in pairs  # adjacent
    platform = geometry.links.index("base_link")
    np.testing.assert_allclose(2 * geometry.table[platform, layout.HALF_EXTENTS], [0.58, 0.38, 0.1])
