"""MJCF models (issue 25 §1): ``wbc.load_robot("x.xml")`` through Pinocchio's MJCF parser, the
joints of one body (a composite joint in Pinocchio) expanded into wbc's 1-DOF chain. Oracles: the
URDF youBot, and Pinocchio's own model of the MJCF."""

from __future__ import annotations

import shutil

import numpy as np
import pinocchio as pin
import pytest

import wbc
from wbc.model.mjcf import MIN_PIN_FOR_COMPOSITES

#: Pinocchio expands an MJCF body's several joints (a composite joint) the way wbc reads it
COMPOSITES = tuple(int(part) for part in pin.__version__.split(".")[:2]) >= MIN_PIN_FOR_COMPOSITES
needs_composites = pytest.mark.skipif(not COMPOSITES, reason=f"pin {pin.__version__}: an MJCF body with several "
                                      "joints is refused below pin 4 (wbc.model.mjcf)")

BODY_WITH_THREE_JOINTS = """<mujoco model="three">
  <compiler angle="radian"/>
  <worldbody>
    <body name="a" pos="0.1 0.2 0.3" euler="0.3 0.2 0.1">
      <joint name="h1" type="hinge" axis="0 0 1" pos="0.05 0 0" range="-1 1"/>
      <joint name="h2" type="hinge" axis="1 0 0" pos="0 0.07 0.02" range="-1.5 1.5"/>
      <joint name="s1" type="slide" axis="0 1 1" range="-0.2 0.2"/>
      <inertial pos="0 0 0.1" mass="1" diaginertia="0.1 0.1 0.1"/>
      <body name="b" pos="0.3 0 0">
        <joint name="h3" type="hinge" axis="0 1 0"/>
        <inertial pos="0 0 0.1" mass="2" diaginertia="0.1 0.1 0.1"/>
        <site name="tip" pos="0.2 0 0"/>
      </body>
    </body>
  </worldbody>
  {equality}
</mujoco>
"""


@needs_composites
def test_the_mjcf_youbot_is_the_urdf_youbot(tmp_path, rng):
    urdf = wbc.load_robot("youbot")
    mjcf = wbc.load_robot(wbc.model_path("youbot", "mjcf"))  # with its sidecar: the same base
    assert mjcf.joint_names == urdf.joint_names and mjcf.base == urdf.base
    alone = tmp_path / "bare.xml"  # without a sidecar: the (x, y, yaw) chain is read as a planar base
    shutil.copy(wbc.model_path("youbot", "mjcf"), alone)
    bare = wbc.load_robot(alone)
    assert bare.base.kind is wbc.BaseKind.PLANAR and bare.base.indices == (0, 1, 2)
    for _ in range(10):
        q = urdf.random_configuration(rng, base_range=2.0)
        for robot in (mjcf, bare):
            np.testing.assert_allclose(robot.frame_pose(q, "ee"), urdf.frame_pose(q, "ee"), atol=1e-12)
            np.testing.assert_allclose(robot.frame_jacobian(q, "ee"), urdf.frame_jacobian(q, "ee"), atol=1e-12)
    np.testing.assert_allclose(mjcf.lower[3:], urdf.lower[3:])


@needs_composites
def test_the_joints_of_one_body_become_a_chain_with_pinocchios_kinematics(tmp_path, rng):
    path = tmp_path / "three.xml"
    path.write_text(BODY_WITH_THREE_JOINTS.format(equality=""))
    robot = wbc.load_robot(path)
    reference = pin.buildModelFromMJCF(str(path))  # h1, h2, s1 in one composite joint
    assert robot.joint_names == ["h1", "h2", "s1", "h3"] and reference.njoints == 3
    np.testing.assert_allclose(robot.lower[:3], [-1.0, -1.5, -0.2])
    data = reference.createData()
    for _ in range(10):
        q = rng.uniform(-1.0, 1.0, 4)
        pin.framesForwardKinematics(reference, data, q)
        np.testing.assert_allclose(robot.frame_pose(q, "tip"), data.oMf[reference.getFrameId("tip")].homogeneous,
                                   atol=1e-12)
        np.testing.assert_allclose(robot.frame_jacobian(q, "tip"),
                                   pin.computeFrameJacobian(reference, data, q, reference.getFrameId("tip"),
                                                            pin.LOCAL_WORLD_ALIGNED), atol=1e-12)
        np.testing.assert_allclose(pin.centerOfMass(robot.model, robot.model.createData(), q),
                                   pin.centerOfMass(reference, data, q), atol=1e-12)


@pytest.mark.skipif(COMPOSITES, reason=f"pin {pin.__version__} expands composite joints")
def test_an_older_pinocchio_refuses_a_body_with_several_joints_naming_the_fix(tmp_path):
    path = tmp_path / "three.xml"
    path.write_text(BODY_WITH_THREE_JOINTS.format(equality=""))
    with pytest.raises(wbc.ModelError, match=r"several joints needs pinocchio >= 4\.0.*pip install -U pin"):
        wbc.load_robot(path)


def test_mjcf_equality_constraints_are_said_and_a_broken_file_is_a_model_error(tmp_path):
    path = tmp_path / "loop.xml"  # one joint per body: read by every supported pin
    path.write_text('<mujoco><compiler angle="radian"/><worldbody><body name="a"><joint name="h1" axis="0 0 1"/>'
                    '<inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/><body name="b" pos="0.3 0 0">'
                    '<joint name="h3" axis="0 1 0"/><inertial pos="0 0 0.1" mass="1" diaginertia="0.1 0.1 0.1"/>'
                    '</body></body></worldbody><equality><joint joint1="h1" joint2="h3"/></equality></mujoco>')
    with pytest.warns(wbc.ModelWarning, match=r"<equality> constraints .* are not modelled"):
        wbc.load_robot(path)
    broken = tmp_path / "broken.xml"
    broken.write_text("<mujoco><worldbody><body>")
    with pytest.raises(wbc.ModelError, match="cannot parse MJCF"):
        wbc.load_robot(broken)


def test_an_mjcf_freejoint_is_a_floating_base(tmp_path):
    path = tmp_path / "flyer.xml"
    path.write_text('<mujoco><compiler angle="radian"/><worldbody><body name="torso"><freejoint name="root"/>'
                    '<inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/><body name="arm" pos="0 0 0.2">'
                    '<joint name="j" axis="0 1 0" range="-1 1"/>'
                    '<inertial pos="0 0 0.1" mass="1" diaginertia="0.1 0.1 0.1"/></body></body></worldbody></mujoco>')
    robot = wbc.load_robot(path)
    assert robot.base.kind is wbc.BaseKind.FLOATING and (robot.nq, robot.nv) == (8, 7)
