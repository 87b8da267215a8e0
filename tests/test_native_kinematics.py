"""The compiled forward kinematics (wbc.model.kinematics native mode, wbc.runtime.kernels.forward_kinematics)
against Pinocchio: joint placements and Jacobians, and the commands of whole controllers."""

import subprocess
import sys
import textwrap

import numpy as np
import pinocchio as pin
import pytest

import wbc
from conftest import NEUTRAL, TASKS, child_environment
from wbc.app.scenario import load_scenario
from wbc.model import kinematics
from wbc.model.kinematics import Kinematics, native_chain

MIXED = """<robot name="mixed">
  <link name="world"/><link name="a"/><link name="b"/><link name="c"/><link name="d"/><link name="tip"/>
  <joint name="slide" type="prismatic"><parent link="world"/><child link="a"/><axis xyz="0.6 0 0.8"/>
    <origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 0.1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="tilt" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0.6 -0.8"/>
    <origin xyz="0 0.1 0.2" rpy="-0.4 0.2 0.9"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="yaw" type="revolute"><parent link="b"/><child link="c"/><axis xyz="0 0 1"/>
    <origin xyz="0.3 0 0" rpy="0 0.5 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="lift" type="prismatic"><parent link="c"/><child link="d"/><axis xyz="0 1 0"/>
    <origin xyz="0 0 0.2" rpy="0.1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="tool" type="fixed"><parent link="d"/><child link="tip"/><origin xyz="0.1 0 0.05"/></joint>
</robot>"""


@pytest.fixture(scope="module")
def robots(tmp_path_factory):
    path = tmp_path_factory.mktemp("mixed") / "mixed.urdf"
    path.write_text(MIXED)
    return [wbc.load_robot(name) for name in wbc.model.robot.shipped_models()] + [wbc.load_robot(path)]


def test_placements_and_jacobians_are_pinocchios(robots, rng):
    """Every shipped robot and a chain of unaligned revolute / prismatic joints with rotated
    placements: data.oMi and data.J of Pinocchio, to rounding, at 50 random configurations."""
    for robot in robots:
        kin = Kinematics(robot)
        assert kin.native, robot.name
        for _ in range(50):
            q = robot.random_configuration(rng)
            kin.update(q)
            data = robot.model.createData()
            pin.computeJointJacobians(robot.model, data, q)
            np.testing.assert_allclose(kin.joint_jacobians, data.J, rtol=0, atol=1e-12)
            for j in range(1, robot.model.njoints):
                _, rotation, translation = kin.joint_views(j)
                np.testing.assert_allclose(rotation, data.oMi[j].rotation, rtol=0, atol=1e-12)
                np.testing.assert_allclose(translation, data.oMi[j].translation, rtol=0, atol=1e-12)


def test_pinocchios_data_follows_on_demand(robots, rng):
    robot = robots[-1]
    kin = Kinematics(robot)
    q = robot.random_configuration(rng)
    kin.update(q, deferred=True)
    frame = robot.frame_id("tip")
    reference = robot.model.createData()
    pin.framesForwardKinematics(robot.model, reference, q)
    np.testing.assert_allclose(kin.frame_placement(frame).homogeneous, reference.oMf[frame].homogeneous, atol=1e-12)
    np.testing.assert_allclose(kin.data.oMi[4].translation, reference.oMi[4].translation, atol=1e-12)


def test_continuous_joints_fall_back_to_pinocchio(tmp_path, rng):
    """A continuous joint (cos, sin: nq 2) is not a chain the kernel knows: Pinocchio computes."""
    path = tmp_path / "wheel.urdf"
    path.write_text(MIXED.replace('name="yaw" type="revolute"', 'name="yaw" type="continuous"'))
    robot = wbc.load_robot(path)
    assert native_chain(robot.model) is None
    task = wbc.PositionTask("tip", gain=0.5)
    q = robot.random_configuration(rng)
    task.set_target(robot.frame_pose(q, "tip")[:3, 3] + 0.05)
    controller = wbc.Controller(robot, [task], [wbc.JointVelocityLimits()])
    assert not controller.kinematics.native
    controller.step(q)
    assert controller.last.success


@pytest.mark.parametrize("scenario_file", sorted(p.name for p in TASKS.glob("*.toml")))
def test_controller_commands_match_the_pinocchio_path(scenario_file, monkeypatch):
    scenario = load_scenario(TASKS / scenario_file)

    def run() -> np.ndarray:
        controller = scenario.make_controller()
        q, out = scenario.q0.copy(), []
        for k in range(120):
            if scenario.reference_task is not None:
                scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
            out.append(controller.step(q))
            q = scenario.robot.integrate(q, out[-1], scenario.dt)
        return np.array(out), controller

    native, controller = run()
    assert controller.kinematics.native
    monkeypatch.setattr(kinematics, "NATIVE_FORWARD_KINEMATICS", False)
    reference, controller = run()
    assert not controller.kinematics.native
    np.testing.assert_allclose(native, reference, rtol=0, atol=1e-10)


def test_a_new_kinematics_holds_the_neutral_configuration(robots):
    """Built, a Kinematics holds the neutral configuration's placements and Jacobians (computed by
    Pinocchio, not the compiled chain): those the compiled chain gives for it."""
    for robot in robots:
        kin = Kinematics(robot)
        placements, jacobians = kin.placements.copy(), kin.joint_jacobians.copy()
        kin.update(pin.neutral(robot.model))  # the compiled chain
        np.testing.assert_allclose(placements, kin.placements, rtol=0, atol=1e-12, err_msg=robot.name)
        np.testing.assert_allclose(jacobians, kin.joint_jacobians, rtol=0, atol=1e-12, err_msg=robot.name)


def test_a_native_controller_does_not_compile_the_python_forward_kinematics():
    """Its tick program runs the chain (op FORWARD_KINEMATICS): the Python entry
    kernels.forward_kinematics is compiled only for controllers whose Python items read the
    kinematics before the program (and there when they are built: test_no_compile_in_ticks)."""
    code = """
        import wbc
        from wbc.runtime import kernels
        robot = wbc.load_robot("youbot")
        controller = wbc.Controller(robot, tasks=[wbc.FrameTask("ee", 1.0, 0.5), wbc.PostureTask(cost=1e-3)])
        native = "forward_kinematics" in vars(kernels)
        wbc.Controller(robot, tasks=[wbc.ManipulabilityTask("ee", cost=1e-3, target=0.05), wbc.PostureTask(cost=1e-3)])
        print(native, "forward_kinematics" in vars(kernels))
    """
    result = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                            env=child_environment(), cwd=NEUTRAL, timeout=600)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["False", "True"]
