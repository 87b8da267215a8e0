"""Mimic joints (issue 25 §3): a URDF ``<mimic>`` joint follows its leader,
``v_joint = multiplier v_leader``, through the MimicJoints rows every controller of the robot adds;
Franka's Panda (example-robot-data) closes its two fingers together."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import wbc
from test_floating_base import robot_data
from wbc.model.couplings import JointCoupling

CHAIN = """<robot name="pincer">
  <link name="base"/><link name="a"/><link name="b"/><link name="c"/>
  <joint name="leader" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" velocity="2" effort="1"/></joint>
  <joint name="follower" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.3 0 0"/>
    <axis xyz="0 0 1"/><mimic joint="leader" multiplier="-2" offset="0.1"/>
    <limit lower="-3" upper="3" velocity="4" effort="1"/></joint>
  <joint name="tip" type="prismatic"><parent link="b"/><child link="c"/><origin xyz="0.2 0 0"/>
    <axis xyz="1 0 0"/><limit lower="-0.1" upper="0.1" velocity="1" effort="1"/></joint>
</robot>
"""


def pincer(tmp_path: Path, **kwargs) -> wbc.Robot:
    path = tmp_path / "pincer.urdf"
    path.write_text(CHAIN)
    return wbc.load_robot(path, **kwargs)


def test_panda_fingers_move_together():
    """A posture pulls finger 1 open and finger 2 shut while the hand moves: the coupling holds
    (written out: v_finger2 = v_finger1 every tick), the fingers meet in the middle."""
    robot = wbc.load_robot(robot_data("panda_description/urdf/panda.urdf"))
    assert robot.couplings == (JointCoupling("panda_finger_joint2", "panda_finger_joint1", 1.0, 0.0),)
    finger1, finger2 = (robot.model.joints[robot.model.getJointId(f"panda_finger_joint{i}")].idx_v for i in (1, 2))
    q = robot.neutral()
    q[:7] = [0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.8]
    hand = wbc.FrameTask("panda_hand", gain=0.3)
    target = robot.frame_pose(q, "panda_hand")
    target[:3, 3] += [0.1, 0.1, -0.1]
    hand.set_target(target)
    apart = q.copy()
    apart[finger1], apart[finger2] = 0.04, 0.0
    fingers = wbc.PostureTask(0.1, target=apart, joints=["panda_finger_joint1", "panda_finger_joint2"])
    controller = wbc.Controller(robot, [hand, fingers],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    assert any(isinstance(c, wbc.MimicJoints) for c in controller.constraints)  # added for the robot
    for _ in range(200):
        v = controller.step(q)
        assert controller.last.success
        assert v[finger2] == pytest.approx(v[finger1], abs=1e-9)
        q = robot.integrate(q, v, controller.dt)
    assert q[finger1] == pytest.approx(0.02, abs=1e-4) and q[finger2] == pytest.approx(q[finger1], abs=1e-8)
    np.testing.assert_allclose(robot.frame_pose(q, "panda_hand")[:3, 3], target[:3, 3], atol=1e-3)


def test_a_multiplier_and_offset_are_kept_along_the_path(tmp_path):
    robot = pincer(tmp_path)
    assert robot.couplings == (JointCoupling("follower", "leader", -2.0, 0.1),)
    q = np.array([0.2, -2 * 0.2 + 0.1, 0.0])  # the coupling holds at the start
    task = wbc.PositionTask("c", gain=0.5)
    task.set_target([0.35, 0.2, 0.0])
    controller = wbc.Controller(robot, [task], [wbc.JointVelocityLimits()])
    for _ in range(100):
        v = controller.step(q)
        assert v[1] == pytest.approx(-2.0 * v[0], abs=1e-9)
        q = robot.integrate(q, v, controller.dt)
    assert q[1] == pytest.approx(-2.0 * q[0] + 0.1, abs=1e-9) and abs(q[0] - 0.2) > 0.05  # it moved


def test_locking_the_leader_alone_is_refused_naming_the_fix(tmp_path):
    with pytest.raises(wbc.ModelError, match="lock 'follower' too"):
        pincer(tmp_path, lock=["leader"])
    assert pincer(tmp_path, lock=["follower", "leader"]).couplings == ()


@pytest.mark.parametrize("couplings, error, message", [
    ([("tip", "leader")], wbc.InvalidInputError, r"\(joint, leader, multiplier\) triple"),
    ([("tip", "nope", 1.0)], wbc.ModelError, "locked or not a joint"),
    ([("tip", "tip", 1.0)], wbc.ModelError, "coupled to itself or twice"),
])
def test_bad_couplings_are_refused(tmp_path, couplings, error, message):
    robot = pincer(tmp_path)
    with pytest.raises(error, match=message):
        wbc.Controller(robot, [wbc.PostureTask(1.0)], [wbc.MimicJoints(couplings)])
