"""The manipulability of a chosen chain (issue 25 §9): ``joints=[...]`` measures the columns of
those joints only. Checked against the SVD of those columns written out and finite differences;
in closed loop an arm-only barrier protects the arm where the whole-body one does not."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import wbc

YOUBOT = wbc.load_robot("youbot")
ARM = [f"arm_joint_{i}" for i in range(1, 6)]
Q0 = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])


@pytest.mark.parametrize("rows, rows_slice", [("all", slice(0, 6)), ("position", slice(0, 3))])
@pytest.mark.parametrize("joints", [ARM, ["arm_joint_2", "arm_joint_3", "arm_joint_4"], ["base_x", "arm_joint_2"]])
def test_the_chain_measure_is_the_product_of_its_columns_singular_values(rows, rows_slice, joints, rng):
    columns = [YOUBOT.model.joints[YOUBOT.model.getJointId(j)].idx_v for j in joints]
    for _ in range(8):
        q = YOUBOT.random_configuration(rng)
        jacobian = YOUBOT.frame_jacobian(q, "ee")[rows_slice][:, columns]
        expected = np.prod(np.linalg.svd(jacobian, compute_uv=False))
        assert wbc.manipulability(YOUBOT, q, "ee", rows, joints) == pytest.approx(expected, rel=1e-12, abs=1e-15)
        gradient = wbc.manipulability_gradient(YOUBOT, q, "ee", rows, joints)
        h = 1e-6
        for k, direction in enumerate(np.eye(YOUBOT.nv)):
            plus = wbc.manipulability(YOUBOT, pin.integrate(YOUBOT.model, q, h * direction), "ee", rows, joints)
            minus = wbc.manipulability(YOUBOT, pin.integrate(YOUBOT.model, q, -h * direction), "ee", rows, joints)
            assert gradient[k] == pytest.approx((plus - minus) / (2 * h), abs=1e-8)


@pytest.mark.parametrize("barrier", [None, "whole body", "arm"])
def test_an_arm_only_barrier_keeps_the_arm_away_from_its_singularity(barrier):
    """The gripper sent 1.2 m up: the arm stretches toward its upright singularity. The base keeps
    the whole-body (position) measure large, so a whole-body barrier at 0.01 lets the arm's own
    measure fall ~1000x below it; the arm-only barrier keeps the arm's at 0.01."""
    reach = wbc.PositionTask("ee", gain=0.5)
    reach.set_target([0.3, 0.0, 1.2])
    constraints = [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()]
    if barrier is not None:
        constraints.append(wbc.ManipulabilityBarrier("ee", 0.01, rows="position",
                                                     joints=ARM if barrier == "arm" else None))
    controller = wbc.Controller(YOUBOT, [reach, wbc.PostureTask(1e-4)], constraints)
    q, arm_measure = Q0.copy(), []
    for _ in range(500):
        v = controller.step(q)
        assert controller.last.success
        q = YOUBOT.integrate(q, v, controller.dt)
        arm_measure.append(wbc.manipulability(YOUBOT, q, "ee", "position", ARM))
    if barrier == "arm":
        assert min(arm_measure) >= 0.01 - 1e-6
    else:
        assert min(arm_measure) < 1e-4


def test_the_task_and_the_barrier_take_a_chain():
    task = wbc.ManipulabilityTask("ee", 1.0, target=0.05, rows="position", joints=ARM)
    barrier = wbc.ManipulabilityBarrier("ee", 0.01, joints=ARM)
    assert repr(task).endswith(f"joints={ARM!r})") and repr(barrier).endswith(f"joints={ARM!r})")
    controller = wbc.Controller(YOUBOT, [task], [wbc.JointVelocityLimits(), barrier])
    controller.step(Q0)
    assert controller.data(barrier).value == pytest.approx(wbc.manipulability(YOUBOT, Q0, "ee", "all", ARM))
    assert controller.data(task).value == pytest.approx(wbc.manipulability(YOUBOT, Q0, "ee", "position", ARM))


@pytest.mark.parametrize("joints, error, message", [
    ("arm_joint_1", wbc.InvalidInputError, r"write joints=\['arm_joint_1'\]"),
    ([], wbc.InvalidInputError, "non-empty list"),
    (["arm_joint2"], wbc.ModelError, "did you mean 'arm_joint_2'"),
    (["arm_joint_2", "arm_joint_2"], wbc.InvalidInputError, "named twice"),
    (["arm_joint_4"], wbc.InvalidInputError, "does not move frame 'arm_link_2'"),
])
def test_bad_chains_are_refused(joints, error, message):
    with pytest.raises(error, match=message):
        wbc.manipulability(YOUBOT, Q0, "arm_link_2", "all", joints)
