"""Floating bases (issue 25 §1-§2): a free-flyer root joint, its SE(3) integration and
base-frame twist, a URDF ``floating`` root joint recognised, and Solo-12 from example-robot-data
keeping its centre of mass over its support triangle while it lifts a foot (Pinocchio: oracle)."""

from __future__ import annotations

import importlib.metadata
import os
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import wbc
from wbc.model.kinematics import Kinematics

ARM = """<robot name="{name}">
  <link name="world"/>
  <link name="body"><inertial><mass value="2.0"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/>
  </inertial></link>
  <link name="arm"><inertial><mass value="1.0"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/>
  </inertial></link>
  {root}
  <joint name="shoulder" type="revolute"><parent link="body"/><child link="arm"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="1.5" effort="10"/></joint>
</robot>
"""
FIXED_ROOT = '<joint name="mount" type="fixed"><parent link="world"/><child link="body"/></joint>'
FLOATING_ROOT = '<joint name="free" type="floating"><parent link="world"/><child link="body"/></joint>'
PLANAR_ROOT = ('<joint name="slide" type="planar"><parent link="world"/><child link="body"/><axis xyz="0 0 1"/>'
               '<limit lower="-9" upper="9" velocity="1" effort="1"/></joint>')


def robot_data(relative: str) -> Path:
    try:
        distribution = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        if os.environ.get("WBC_REQUIRE_EXTRAS") == "1":
            raise
        pytest.skip('needs example-robot-data (in the [test] extra): pip install "wbc[test]"')
    return Path(distribution.locate_file(f"cmeel.prefix/share/example-robot-data/robots/{relative}"))


def write(tmp_path: Path, root: str, name: str = "flyer") -> Path:
    path = tmp_path / f"{name}.urdf"
    path.write_text(ARM.format(name=name, root=root))
    return path


def test_a_urdf_floating_root_joint_is_a_floating_base(tmp_path):
    robot = wbc.load_robot(write(tmp_path, FLOATING_ROOT))
    assert robot.base.kind is wbc.BaseKind.FLOATING and (robot.nq, robot.nv) == (8, 7)
    np.testing.assert_array_equal(robot.neutral()[:7], [0, 0, 0, 0, 0, 0, 1])  # quaternion (x, y, z, w)
    assert wbc.PostureTask(1.0).bind(robot).indices.tolist() == [6]  # the base is not a posture coordinate


def test_declared_floating_base_adds_a_free_flyer_with_its_speed_bounds(tmp_path):
    path = write(tmp_path, FIXED_ROOT)  # a fixed robot, unless declared
    assert wbc.load_robot(path).base.kind is wbc.BaseKind.FIXED
    robot = wbc.load_robot(path, base="floating", max_linear_speed=0.5, max_yaw_rate=0.8)
    assert robot.model.joints[1].shortname() == "JointModelFreeFlyer" and robot.nv == 7
    np.testing.assert_array_equal(robot.velocity_limit, [0.5, 0.5, 0.5, 0.8, 0.8, 0.8, 1.5])
    np.testing.assert_array_equal(robot.lower[3:7], -1.0)
    mass = sum(inertia.mass for inertia in robot.model.inertias)
    assert mass == pytest.approx(3.0)  # the root link's inertia rides on the free flyer
    sidecar = path.with_suffix(".toml")
    sidecar.write_text('[base]\nkind = "floating"\nmax_linear_speed = 0.5\n')
    from_sidecar = wbc.load_robot(path)
    assert from_sidecar.base.kind is wbc.BaseKind.FLOATING and from_sidecar.velocity_limit[0] == 0.5


@pytest.mark.parametrize("root, kwargs, message", [
    (FIXED_ROOT, {"wheels": ["shoulder"]}, "a floating base has no wheels"),
    (FIXED_ROOT, {"lock": ["root_joint"]}, "lock holds the free-flyer root joint"),
    (PLANAR_ROOT, {}, "already is a planar base"),
])
def test_a_floating_base_that_does_not_fit_is_refused_naming_the_fix(tmp_path, root, kwargs, message):
    with pytest.raises(wbc.ModelError, match=message):
        wbc.load_robot(write(tmp_path, root), base="floating", **kwargs)


def test_the_base_twist_is_in_the_base_frame_and_integrates_on_se3(tmp_path):
    """A constant base-frame twist (forward speed u, yaw rate w) drives the base on a circle:
    written out, p(t) = p0 + R0 (u/w sin wt, u/w (1 - cos wt), 0), R(t) = R0 Rz(wt)."""
    robot = wbc.load_robot(write(tmp_path, FLOATING_ROOT))
    q = robot.neutral()
    q[:3] = [0.5, -0.2, 1.0]
    q[3:7] = np.array([0.2, -0.1, 0.3, 0.9]) / np.linalg.norm([0.2, -0.1, 0.3, 0.9])
    R0 = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()  # Pinocchio's order: (w, x, y, z)
    u, w, t = 0.7, 1.3, 0.9
    v = np.array([u, 0.0, 0.0, 0.0, 0.0, w, 0.4])
    moved = robot.integrate(q, v, t)
    pose = robot.frame_pose(moved, "body")
    c, s = np.cos(w * t), np.sin(w * t)
    np.testing.assert_allclose(pose[:3, 3], q[:3] + R0 @ [u / w * s, u / w * (1 - c), 0.0], atol=1e-12)
    np.testing.assert_allclose(pose[:3, :3], R0 @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]), atol=1e-12)
    assert moved[7] == pytest.approx(q[7] + 0.4 * t)
    assert np.linalg.norm(moved[3:7]) == pytest.approx(1.0)
    np.testing.assert_allclose(robot.base.twist(q, v), v[:6])


def test_random_configurations_hold_unit_quaternions(tmp_path):
    robot = wbc.load_robot(write(tmp_path, FLOATING_ROOT))
    rng = np.random.default_rng(3)
    for _ in range(5):
        assert np.linalg.norm(robot.random_configuration(rng)[3:7]) == pytest.approx(1.0)


SOLO_STANDING = [0.0, 0.8, -1.6, 0.0, 0.8, -1.6, 0.0, -0.8, 1.6, 0.0, -0.8, 1.6]  # legs FL, FR, HL, HR


def counter_clockwise(points: np.ndarray) -> np.ndarray:
    centre = points.mean(axis=0)
    return points[np.argsort(np.arctan2(*(points - centre).T[::-1]))]


def test_solo_lifts_a_foot_with_its_centre_of_mass_over_the_other_three():
    """Solo-12 on a floating base: three feet held (a strict top priority), the fourth lifted
    5 cm and moved 3 cm forward. The standing robot's centre of mass lies on the diagonal FR-HL,
    an edge of the support triangle, so the 2-cm margin of SupportPolygon must move the body
    to lift the foot. Pinocchio computes the centre of mass and the feet at every tick."""
    robot = wbc.load_robot(robot_data("solo_description/robots/solo12.urdf"), base="floating")
    assert (robot.nq, robot.nv) == (19, 18)
    assert not Kinematics(robot).native  # the compiled chain drives 1-DOF joints: Pinocchio's kinematics here
    model, data = robot.model, robot.model.createData()
    q = robot.neutral()
    q[2], q[7:] = 0.235, SOLO_STANDING
    stance = ["FR_FOOT", "HL_FOOT", "HR_FOOT"]
    feet = {name: robot.frame_pose(q, name)[:3, 3] for name in [*stance, "FL_FOOT"]}
    holds = []
    for name in stance:
        hold = wbc.PositionTask(name, gain=1.0)
        hold.set_target(feet[name])
        holds.append(hold)
    target = feet["FL_FOOT"] + [0.03, 0.0, 0.05]
    swing = wbc.PositionTask("FL_FOOT", gain=0.2, max_speed=0.5)
    swing.set_target(target)
    triangle = counter_clockwise(np.array([feet[name][:2] for name in stance]))
    margin = 0.02
    controller = wbc.Controller(robot, [holds, [swing, wbc.PostureTask(1e-3, target=q)]],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(),
                                 wbc.SupportPolygon(triangle.tolist(), margin=margin)])
    start = q.copy()
    edges = np.roll(triangle, -1, axis=0) - triangle
    normals = np.c_[edges[:, 1], -edges[:, 0]] / np.linalg.norm(edges, axis=1)[:, None]  # outward (ccw)
    for tick in range(250):
        v = controller.step(q)
        assert controller.last.success
        q = robot.integrate(q, v, controller.dt)
        com = pin.centerOfMass(model, data, q)
        outside = np.einsum("ij,ij->i", normals, com[:2] - triangle).max()  # > 0: outside an edge
        assert outside <= (1e-9 if tick < 20 else -margin + 1e-6)  # the margin is reached in a few ticks, then kept
        pin.framesForwardKinematics(model, data, q)
        for name in stance:  # held to first order: a linearisation error of < 1 mm, removed by the feedback
            np.testing.assert_allclose(data.oMf[model.getFrameId(name)].translation, feet[name], atol=1e-3)
    pin.framesForwardKinematics(model, data, q)
    for name in stance:
        np.testing.assert_allclose(data.oMf[model.getFrameId(name)].translation, feet[name], atol=1e-6)
    np.testing.assert_allclose(data.oMf[model.getFrameId("FL_FOOT")].translation, target, atol=5e-3)
    assert np.linalg.norm(q[:3] - start[:3]) > 5e-3  # the body moved to keep the balance
    assert np.linalg.norm(q[3:7]) == pytest.approx(1.0)


def test_talos_loads_on_a_floating_base_fast_and_its_poses_are_pinocchios():
    """Loading parses the URDF once (Pinocchio: milliseconds); the kernels are compiled once per
    install and cached, not per load. Poses and the centre of mass agree with Pinocchio's own
    free-flyer model of the URDF."""
    path = robot_data("talos_data/robots/talos_reduced.urdf")
    robot = wbc.load_robot(path, base="floating")
    assert robot.couplings == ()  # its grippers' <mimic> joints are fixed joints in talos_reduced.urdf
    reference = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    assert (robot.nq, robot.nv) == (reference.nq, reference.nv) == (39, 38)
    q = pin.normalize(reference, np.random.default_rng(1).uniform(-0.5, 0.5, reference.nq))
    data = reference.createData()
    pin.framesForwardKinematics(reference, data, q)
    for frame in ("gripper_left_base_link", "left_sole_link"):
        np.testing.assert_allclose(robot.frame_pose(q, frame), data.oMf[reference.getFrameId(frame)].homogeneous,
                                   atol=1e-12)
