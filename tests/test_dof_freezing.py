"""DofFreezing (issue 25 §10): frozen joints do not move, on every tick and with every form; the
others do the work; bad joint lists are refused naming the fix."""

from __future__ import annotations

import numpy as np
import pytest

import wbc

YOUBOT = wbc.load_robot("youbot")
Q0 = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])


@pytest.mark.parametrize("solver", ["daqp", "osqp", "proxqp"])
def test_frozen_joints_stay_and_the_others_reach_the_target(solver):
    goal = YOUBOT.frame_pose(Q0, "ee")[:3, 3] + [0.3, 0.2, 0.1]
    reach = wbc.PositionTask("ee", gain=0.3)
    reach.set_target(goal)
    frozen = wbc.DofFreezing(["arm_joint_1", "arm_joint_3", "base_yaw"])
    controller = wbc.Controller(YOUBOT, [reach, wbc.PostureTask(1e-8)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), frozen], solver=solver)
    q = Q0.copy()
    for _ in range(400):
        v = controller.step(q)
        assert controller.last.success
        # base_yaw, arm_joint_1, arm_joint_3: zero within the answer check's tolerance (1e-6 relative)
        assert np.abs(v[[2, 3, 5]]).max() <= 1e-6 * (1 + np.abs(v).max())
        q = YOUBOT.integrate(q, v, controller.dt)
    np.testing.assert_allclose(q[[2, 3, 5]], Q0[[2, 3, 5]], atol=4e-6)
    assert np.linalg.norm(YOUBOT.frame_pose(q, "ee")[:3, 3] - goal) < 1e-4  # the base and the other joints


def test_a_frozen_joint_outside_its_limits_stays_there_and_freezing_all_gives_zero():
    q = Q0.copy()
    q[4] = YOUBOT.upper[4] + 0.2  # past its limit: the position limits ask it back
    limits = [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.DofFreezing(["arm_joint_2"])]
    controller = wbc.Controller(YOUBOT, [wbc.PostureTask(1.0)], limits)
    v = controller.step(q)
    assert controller.last.success and v[4] == pytest.approx(0.0, abs=1e-12)
    every = wbc.DofFreezing(list(YOUBOT.model.names[1:]))
    still = wbc.Controller(YOUBOT, [wbc.PostureTask(1.0, target=Q0 + 0.3)], [every])
    v = still.step(Q0)
    assert still.last.success and np.abs(v).max() <= 1e-12


def test_reduced_nonholonomic_base_with_its_heading_frozen_drives_straight():
    deluca = wbc.load_robot("deluca_mm")
    q = deluca.neutral()
    names = [deluca.model.names[j] for j in range(1, deluca.model.njoints)]
    heading = names[deluca.base.indices[2]]
    reach = wbc.PositionTask("wrist_center", gain=0.3)
    reach.set_target(deluca.frame_pose(q, "wrist_center")[:3, 3] + [0.5, 0.3, 0.0])
    controller = wbc.Controller(deluca, [reach, wbc.PostureTask(1e-3)],
                                [wbc.JointVelocityLimits(), wbc.DofFreezing([heading])], reduced=True)
    for _ in range(200):
        v = controller.step(q)
        assert controller.last.success and abs(v[deluca.base.indices[2]]) <= 1e-9
        q = deluca.integrate(q, v, controller.dt)
    x, y, _ = deluca.base.indices
    assert abs(q[y]) <= 1e-9 and q[x] > 0.1  # no slip, no turning: straight ahead only


@pytest.mark.parametrize("joints, error, message", [
    ("arm_joint_1", wbc.InvalidInputError, r"write joints=\['arm_joint_1'\]"),
    ([], wbc.InvalidInputError, "non-empty list"),
    ([3], wbc.InvalidInputError, "list of joint names"),
])
def test_bad_joint_lists_are_refused(joints, error, message):
    with pytest.raises(error, match=message):
        wbc.DofFreezing(joints)


def test_unknown_and_repeated_joints_are_refused_when_the_controller_is_built():
    with pytest.raises(wbc.ModelError, match="did you mean 'arm_joint_2'"):
        wbc.Controller(YOUBOT, [wbc.PostureTask(1.0)], [wbc.DofFreezing(["arm_joint2"])])
    with pytest.raises(wbc.InvalidInputError, match="named twice"):
        wbc.Controller(YOUBOT, [wbc.PostureTask(1.0)], [wbc.DofFreezing(["arm_joint_2", "arm_joint_2"])])
