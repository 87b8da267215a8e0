"""CoMTask and SupportPolygon (issue 25 §8): the centre-of-mass Jacobian against the links'
mass-weighted Jacobians written out, the polygon's rows against finite differences, a tall
reach that tips the centre of mass out of a small polygon without the constraint and keeps it in
with it, and bad input."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pinocchio as pin
import pytest

import wbc
from wbc.model.kinematics import Kinematics
from wbc.tasks.com_task import center_of_mass

YOUBOT = wbc.load_robot("youbot")
Q0 = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])
SQUARE = [[-0.1, -0.1], [0.1, -0.1], [0.1, 0.1], [-0.1, 0.1]]


def test_the_com_jacobian_is_the_mass_weighted_mean_of_the_links(rng):
    """J_c = sum_i m_i J_i(c_i) / M, each link's Jacobian at its own centre of mass (a frame added
    at c_i to a copy of the model, so Pinocchio's frame Jacobian serves as the per-link oracle)."""
    model = YOUBOT.model.copy()
    links = []
    for joint in range(1, model.njoints):
        inertia = model.inertias[joint]
        if inertia.mass > 0:
            frame = pin.Frame(f"com{joint}", joint, 0, pin.SE3(np.eye(3), inertia.lever), pin.FrameType.OP_FRAME)
            links.append((model.addFrame(frame), inertia.mass))
    data = model.createData()
    task = wbc.CoMTask(gain=0.5)
    task.set_target([0.0, 0.0, 0.0])
    rows_of = task.bind(YOUBOT)
    kin = Kinematics(YOUBOT)
    total = sum(mass for _, mass in links)
    for _ in range(10):
        q = YOUBOT.random_configuration(rng)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        expected = sum(mass * pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED)[:3] for f, mass in links)
        position = sum(mass * data.oMf[f].translation for f, mass in links) / total
        kin.update(q)
        jacobian, target = np.zeros((3, YOUBOT.nv)), np.zeros(3)
        rows_of.compute(kin, 0.01, jacobian, target)
        np.testing.assert_allclose(jacobian, expected / total, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rows_of.error, -position, rtol=0, atol=1e-12)  # e = c* - c, c* = 0


def _com_in_base(q):
    pose = YOUBOT.frame_pose(q, "base_link")
    return pose[:3, :3].T @ (center_of_mass(YOUBOT, q) - pose[:3, 3])


@pytest.mark.parametrize("guarded", [False, True])
def test_a_tall_reach_keeps_the_com_over_a_small_polygon_only_with_the_constraint(guarded):
    """The gripper reaches 0.8 m forward with the platform held (a costly base velocity): the
    arm's centre of mass moves forward past x = 0.065 m of the platform without the constraint;
    with it, never (to 1e-6 m), while the base drives to make up the reach."""
    polygon = [[-0.2, -0.15], [0.065, -0.15], [0.065, 0.15], [-0.2, 0.15]]
    reach = wbc.PositionTask("ee", gain=0.2)
    reach.set_target([0.8, 0.0, 0.1])
    still = wbc.BaseVelocityTask(100.0)
    still.set_target([0.0, 0.0, 0.0])
    constraints = [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()]
    if guarded:
        constraints.append(wbc.SupportPolygon(polygon, frame="base_link", gain=0.3))
    controller = wbc.Controller(YOUBOT, [reach, still, wbc.PostureTask(1e-3)], constraints)
    q, forward = Q0.copy(), []
    for _ in range(600):
        v = controller.step(q)
        assert controller.last.success
        q = YOUBOT.integrate(q, v, controller.dt)
        forward.append(_com_in_base(q)[0])
    if guarded:
        assert max(forward) <= 0.065 + 1e-6
        assert np.linalg.norm(YOUBOT.frame_pose(q, "ee")[:3, 3] - [0.8, 0.0, 0.1]) < 0.1  # still reaching
    else:
        assert max(forward) > 0.07


@pytest.mark.parametrize("cost, lifted", [([1.0, 1.0, 0.0], False), ([1.0, 1.0, 1.0], True)])
def test_the_com_task_moves_the_ground_projection_and_z_only_when_weighted(cost, lifted):
    """A target 5 cm forward, 2 cm left and 0.5 m up (out of reach): x and y are reached either
    way; z moves toward the target only when its cost is not 0."""
    start = center_of_mass(YOUBOT, Q0)
    task = wbc.CoMTask(cost=cost, gain=0.3)
    task.set_target(start + [0.05, 0.02, 0.5])
    controller = wbc.Controller(YOUBOT, [task, wbc.PostureTask(1e-6, target=Q0)], [wbc.JointVelocityLimits()])
    q = Q0.copy()
    for _ in range(400):
        q = YOUBOT.integrate(q, controller.step(q), controller.dt)
    moved = center_of_mass(YOUBOT, q) - start
    np.testing.assert_allclose(moved[:2], [0.05, 0.02], atol=1e-4)
    assert (moved[2] > 0.01) if lifted else (abs(moved[2]) < 1e-3)


@pytest.mark.parametrize("polygon, message", [
    ([[0, 0], [1, 0]], "m >= 3"),
    ([[0, 0], [0, 1], [1, 0]], "counter-clockwise"),  # clockwise
    ([[0, 0], [2, 0], [1, 0.2], [1, 1]], "convex"),
    ([[0, 0], [1, 0], [1, 0], [0, 1]], "repeated vertex"),
    ([[0, 0], [1, np.nan], [0, 1]], "NaN or inf"),
    ("square", "numeric"),
    ([[0, 0], [1, 0], [True, 1]], "not true/false"),  # (was read as the vertex (1, 1))
    ([[0, 0], [1, 0], [1j, 1]], "must be real"),
    ([[-1e200, -1e200], [1e200, -1e200], [0, 1e200]], "beyond 1e+150 m"),  # (its turn tests overflowed)
])
def test_a_bad_polygon_is_refused(polygon, message):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (no numpy warning on the way)
        with pytest.raises(wbc.InvalidInputError, match=re.escape(message)):
            wbc.SupportPolygon(polygon)


def test_a_robot_without_mass_and_an_unknown_frame_are_refused():
    puma = wbc.load_robot("puma560")  # a kinematic model: no inertias
    with pytest.raises(wbc.ModelError, match="no mass.*<inertial>"):
        wbc.Controller(puma, [wbc.PostureTask(1.0)], [wbc.SupportPolygon(SQUARE)])
    task = wbc.CoMTask()
    task.set_target([0, 0, 0])
    with pytest.raises(wbc.ModelError, match="no mass"):
        wbc.Controller(puma, [task])
    with pytest.raises(wbc.UnknownFrameError):
        wbc.Controller(YOUBOT, [wbc.PostureTask(1.0)], [wbc.SupportPolygon(SQUARE, frame="base_lnk")])
    with pytest.raises(wbc.InvalidInputError, match="no target"):
        wbc.Controller(YOUBOT, [wbc.CoMTask()]).step(Q0)


def test_both_are_scenario_items(tmp_path):
    from conftest import TASKS
    from wbc.app.scenario import load_scenario

    text = (TASKS / "youbot_reach.toml").read_text()
    text += ('\n[[tasks]]\ntype = "CoMTask"\ncost = [1.0, 1.0, 0.0]\ngain = 0.1\n'
             '\n[[constraints]]\ntype = "SupportPolygon"\nframe = "base_link"\n'
             'polygon = [[-0.2, -0.15], [0.1, -0.15], [0.1, 0.15], [-0.2, 0.15]]\nmargin = 0.01\n')
    path = tmp_path / "com.toml"
    path.write_text(text)
    scenario = load_scenario(path)
    assert [type(t).__name__ for t in scenario.tasks][-1] == "CoMTask"
    assert isinstance(scenario.constraints[-1], wbc.SupportPolygon)
    assert scenario.constraints[-1].margin == 0.01
