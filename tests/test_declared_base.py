"""Declared bases (wbc.load_robot(path, base=..., wheels=...)): third-party mobile robots that
come without wbc's base joints get them, and their wheels are read from the model."""

import importlib.metadata
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import wbc
from wbc.model.declared_base import BASE_JOINT_NAMES

RADIUS, HALF_TRACK = 0.0825, 0.21  # the wheels of the URDF below

#: a differential-drive robot whose URDF starts with a `planar` joint (as Reachback's and
#: Stretch's do): two driven wheels, a caster, a two-joint arm
PLANAR_ROBOT = """<?xml version="1.0"?>
<robot name="cart">
  <link name="base_footprint"/>
  <link name="base_link"/>
  <joint name="planar_joint" type="planar">
    <parent link="base_footprint"/><child link="base_link"/>
    <origin xyz="0 0 {lift}" rpy="0 0 0"/><axis xyz="0 0 1"/>
  </joint>
  <link name="wheel_left_link">
    <collision><geometry><cylinder radius="{radius}" length="0.03"/></geometry></collision>
  </link>
  <joint name="wheel_left_joint" type="continuous">
    <parent link="base_link"/><child link="wheel_left_link"/>
    <origin xyz="{axle} {track} 0" rpy="-1.5707963267948966 0 0"/><axis xyz="0 0 1"/>
    <limit effort="5" velocity="12"/>
  </joint>
  <link name="wheel_right_link">
    <collision><geometry><cylinder radius="{radius}" length="0.03"/></geometry></collision>
  </link>
  <joint name="wheel_right_joint" type="continuous">
    <parent link="base_link"/><child link="wheel_right_link"/>
    <origin xyz="{axle} -{track} 0" rpy="-1.5707963267948966 0 0"/><axis xyz="0 0 1"/>
    <limit effort="5" velocity="12"/>
  </joint>
  <link name="caster_link"/>
  <joint name="caster_joint" type="continuous">
    <parent link="base_link"/><child link="caster_link"/>
    <origin xyz="-0.3 0 0"/><axis xyz="0 0 1"/>
  </joint>
  <link name="upper_arm"/>
  <joint name="shoulder" type="revolute">
    <parent link="base_link"/><child link="upper_arm"/>
    <origin xyz="0.1 0 0.4"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1.5"/>
  </joint>
  <link name="forearm"/>
  <joint name="elbow" type="revolute">
    <parent link="upper_arm"/><child link="forearm"/>
    <origin xyz="0 0 0.35"/><axis xyz="0 1 0"/><limit lower="-2.5" upper="2.5" effort="1" velocity="1.5"/>
  </joint>
  <link name="tool"/>
  <joint name="tool_joint" type="fixed"><parent link="forearm"/><child link="tool"/><origin xyz="0 0 0.3"/></joint>
</robot>
"""


def write_robot(folder: Path, name: str = "cart", lift: float = 0.05, axle: float = 0.0, track: float = HALF_TRACK,
                radius: float = RADIUS) -> Path:
    path = folder / f"{name}.urdf"
    path.write_text(PLANAR_ROBOT.format(lift=lift, axle=axle, track=track, radius=radius))
    return path


def load_quietly(path: Path, *args, **kwargs) -> wbc.Robot:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wbc.ModelWarning)
        return wbc.load_robot(path, *args, **kwargs)


def test_a_planar_root_joint_becomes_wbcs_base_with_the_same_kinematics(tmp_path, rng):
    """Oracle: Pinocchio's model of the URDF as written, the planar joint at (x, y, cos, sin)."""
    path = write_robot(tmp_path)
    robot = load_quietly(path, "differential", wheels=["wheel_right_joint", "wheel_left_joint"],
                         lock=["caster_joint"])
    original = pin.buildModelFromUrdf(str(path))
    data = original.createData()
    assert robot.model.names[1:4].tolist() == list(BASE_JOINT_NAMES)
    assert robot.nq == robot.nv == 5 and robot.base.indices == (0, 1, 2)
    for _ in range(20):
        q = robot.random_configuration(rng, base_range=3.0)
        q_original = pin.neutral(original)
        planar = original.joints[original.getJointId("planar_joint")]
        q_original[planar.idx_q:planar.idx_q + 4] = [q[0], q[1], np.cos(q[2]), np.sin(q[2])]
        for joint in ("shoulder", "elbow"):
            j = original.joints[original.getJointId(joint)]
            q_original[j.idx_q] = q[robot.model.joints[robot.model.getJointId(joint)].idx_q]
        pin.framesForwardKinematics(original, data, q_original)
        for frame in ("tool", "base_link", "wheel_left_link"):
            np.testing.assert_allclose(robot.frame_pose(q, frame), data.oMf[original.getFrameId(frame)].homogeneous,
                                       atol=1e-12)


def test_the_differential_wheels_are_read_from_the_urdf(tmp_path):
    robot = load_quietly(write_robot(tmp_path), "differential", wheels=["wheel_left_joint", "wheel_right_joint"],
                         lock=["caster_joint"])
    wheels = robot.base.wheels
    assert isinstance(wheels, wbc.DifferentialWheels) and robot.base.kind is wbc.BaseKind.UNICYCLE
    assert (wheels.radius, wheels.half_track, wheels.max_speed) == (RADIUS, HALF_TRACK, 12.0)
    # v = 0.4 m/s forward while turning at 0.5 rad/s: u = (v -+ b omega) / r, left then right
    q, v = np.zeros(robot.nq), np.zeros(robot.nv)
    v[0], v[2] = 0.4, 0.5
    np.testing.assert_allclose(robot.wheel_speeds(q, v), [(0.4 - HALF_TRACK * 0.5) / RADIUS,
                                                          (0.4 + HALF_TRACK * 0.5) / RADIUS])


def test_a_declared_differential_base_drives_the_tool_to_its_side_without_slipping(tmp_path):
    robot = load_quietly(write_robot(tmp_path), "differential", wheels=["wheel_left_joint", "wheel_right_joint"],
                         lock=["caster_joint"], max_linear_speed=0.5, max_yaw_rate=1.0)
    q = robot.neutral()
    target = robot.frame_pose(q, "tool")[:3, 3] + [0.0, 1.5, 0.0]  # 1.5 m to the left: a differential base turns
    tool = wbc.PositionTask("tool", gain=0.5)
    tool.set_target(target)
    controller = wbc.Controller(robot, [tool, wbc.PostureTask(cost=1e-3)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.NonholonomicBase(),
                                 wbc.WheelSpeedLimits()], dt=0.01)
    slip = 0.0
    for _ in range(2000):
        v = controller.step(q)
        slip = max(slip, abs(robot.base_twist(q, v)[1]))
        assert np.all(np.abs(robot.wheel_speeds(q, v)) <= 12.0 * (1 + 1e-6))
        q = robot.integrate(q, v, 0.01)
    assert slip < 1e-9
    assert np.linalg.norm(robot.frame_pose(q, "tool")[:3, 3] - target) < 1e-4
    assert np.hypot(q[0], q[1]) > 0.5  # the base moved (the arm alone reaches 0.65 m)


def test_without_a_declaration_a_planar_root_joint_is_a_planar_base(tmp_path):
    with pytest.warns(wbc.ModelWarning, match="look like wheels but stay free joints"):
        robot = wbc.load_robot(write_robot(tmp_path))
    assert robot.base.kind is wbc.BaseKind.PLANAR and robot.base.wheels is None
    assert robot.model.names[1:4].tolist() == list(BASE_JOINT_NAMES)


def test_a_mobile_robot_without_a_base_warns_naming_the_fix(tmp_path):
    path = tmp_path / "fixed_cart.urdf"
    text = PLANAR_ROBOT.format(lift=0.0, axle=0.0, track=HALF_TRACK, radius=RADIUS)
    path.write_text(text.replace('type="planar"', 'type="fixed"').replace('<axis xyz="0 0 1"/>\n  </joint>\n  <link '
                                                                           'name="wheel_left_link">',
                                                                           '</joint>\n  <link name="wheel_left_link">'))
    with pytest.warns(wbc.ModelWarning, match=r"look like wheels, but the robot is loaded with a fixed base.*"
                                              r"base='differential'"):
        robot = wbc.load_robot(path)
    assert robot.base.kind is wbc.BaseKind.FIXED
    declared = load_quietly(path, "differential", wheels=["wheel_left_joint", "wheel_right_joint"],
                            lock=["caster_joint"])
    assert declared.model.names[1:4].tolist() == list(BASE_JOINT_NAMES) and declared.nv == 5


@pytest.mark.parametrize("kwargs, message", [
    ({"base": "differential", "wheels": ["wheel_left_joint", "whel_right_joint"]},
     r"wheels: 'whel_right_joint' is not a joint of the model; did you mean 'wheel_right_joint'"),
    ({"base": "differential", "wheels": ["wheel_left_joint", "wheel_right_joint", "caster_joint"]},
     r"a differential base has 2 driven wheels, 3 given .*lock=\[\.\.\.\]"),
    ({"base": "differential", "wheels": ["wheel_left_joint", "wheel_left_joint"]}, r"named twice"),
    ({"base": "hovercraft"}, r"unknown base kind 'hovercraft'; choose one of"),
    ({"base": "floating"}, r"the model's root already is a planar base; declare base='planar'"),
    ({"base": "fixed", "wheels": ["wheel_left_joint"]}, r"a fixed base has no wheels"),
    ({"base": "mecanum", "wheels": ["wheel_left_joint", "wheel_right_joint"]}, r"a mecanum base has 4 driven wheels"),
])
def test_a_declaration_that_does_not_fit_the_model_is_refused(tmp_path, kwargs, message):
    with pytest.raises(wbc.ModelError, match=message):
        load_quietly(write_robot(tmp_path), **kwargs)


def test_wheels_off_the_axle_or_without_a_radius_are_refused_naming_the_fix(tmp_path):
    wheels = {"base": "differential", "wheels": ["wheel_left_joint", "wheel_right_joint"]}
    with pytest.raises(wbc.ModelError, match=r"wheel_left_joint at \[0\.1, 0\.21\].*axle on the base frame's y axis"):
        load_quietly(write_robot(tmp_path, "ahead", axle=0.1), **wheels)
    no_radius = tmp_path / "no_radius.urdf"
    no_radius.write_text(write_robot(tmp_path).read_text().replace(
        f'<collision><geometry><cylinder radius="{RADIUS}" length="0.03"/></geometry></collision>', ""))
    with pytest.raises(wbc.ModelError, match=r"cannot read the radius of wheel 'wheel_left_joint'.*wheel_radius="):
        load_quietly(no_radius, **wheels)
    assert load_quietly(no_radius, **wheels, wheel_radius=0.1).base.wheels.radius == 0.1


def test_a_replaced_root_joint_placed_off_the_root_is_refused(tmp_path):
    path = tmp_path / "offset.urdf"
    path.write_text(write_robot(tmp_path).read_text().replace('<origin xyz="0 0 0.05" rpy="0 0 0"/>',
                                                              '<origin xyz="0.2 0 0.05" rpy="0 0 0"/>'))
    with pytest.raises(wbc.ModelError, match=r"'planar_joint', which the base joints replace, is placed at "
                                             r"\[0\.2, 0\.0, 0\.05\]"):
        load_quietly(path)


def test_a_robot_with_a_sidecar_declares_its_base_there():
    with pytest.raises(wbc.ModelError, match=r"declared by its sidecar's \[base\] table"):
        wbc.load_robot("youbot", "differential")


def test_mimic_joints_are_coupled_on_a_declared_base(tmp_path):
    path = tmp_path / "mimic.urdf"
    path.write_text(write_robot(tmp_path).read_text().replace(
        '<axis xyz="0 1 0"/><limit lower="-2.5"', '<axis xyz="0 1 0"/><mimic joint="shoulder"/><limit lower="-2.5"'))
    robot = wbc.load_robot(path, "planar", lock=["wheel_left_joint", "wheel_right_joint", "caster_joint"])
    assert [(c.joint, c.leader, c.multiplier) for c in robot.couplings] == [("elbow", "shoulder", 1.0)]


# ------------------------------------------------------------------ a real robot: PAL's TIAGo
def tiago_urdf() -> Path:
    try:
        distribution = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        pytest.skip('needs example-robot-data (in the [test] extra): pip install "wbc[test]"')
    return Path(distribution.locate_file(
        "cmeel.prefix/share/example-robot-data/robots/tiago_description/robots/tiago.urdf"))


def test_tiago_loads_with_a_warning_and_drives_on_its_declared_differential_base():
    urdf = tiago_urdf()
    with pytest.warns(wbc.ModelWarning, match=r"\['wheel_left_joint', 'wheel_right_joint'\] look like wheels"):
        assert wbc.load_robot(urdf).base.kind is wbc.BaseKind.FIXED
    robot = wbc.load_robot(urdf, "differential", wheels=["wheel_left_joint", "wheel_right_joint"],
                           max_linear_speed=1.0, max_yaw_rate=1.0)
    # tiago.urdf: wheel links' <cylinder radius="0.0985">, wheel joints at y = +-0.2022, velocity="10.152284264"
    assert robot.base.wheels == wbc.DifferentialWheels(radius=0.0985, half_track=0.2022, max_speed=10.152284264)
    q = robot.neutral()
    target = robot.frame_pose(q, "arm_tool_link")[:3, 3] + [0.0, 2.0, 0.0]
    tool = wbc.PositionTask("arm_tool_link", gain=0.5)
    tool.set_target(target)
    controller = wbc.Controller(robot, [tool, wbc.PostureTask(cost=1e-3)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.NonholonomicBase(),
                                 wbc.WheelSpeedLimits()], dt=0.01)
    slip = 0.0
    for _ in range(1500):
        v = controller.step(q)
        slip = max(slip, abs(robot.base_twist(q, v)[1]))
        q = robot.integrate(q, v, 0.01)
    assert slip < 1e-9 and controller.last.outcome is wbc.Outcome.OPTIMAL
    assert np.linalg.norm(robot.frame_pose(q, "arm_tool_link")[:3, 3] - target) < 1e-4
    assert np.hypot(q[0], q[1]) > 0.3  # the base moved


def test_tiago_avoids_an_obstacle_with_its_package_collision_meshes():
    """TIAGo's <collision> meshes are package://example-robot-data/... paths: CollisionAvoidance
    finds them in the folders above the URDF (as the 3-D view does; it raised ModelError), and its
    margin holds against a ball in the tool's way (coal on the URDF's meshes as the oracle)."""
    import coal
    import pinocchio as pin

    urdf = tiago_urdf()
    robot = wbc.load_robot(urdf, "differential", wheels=["wheel_left_joint", "wheel_right_joint"],
                           max_linear_speed=1.0, max_yaw_rate=1.0)
    q = robot.neutral()
    start = robot.frame_pose(q, "arm_tool_link")[:3, 3]
    ball = wbc.Sphere(start + [0.15, 0.0, 0.0], 0.05)
    avoidance = wbc.CollisionAvoidance([ball], self_collision=False, min_distance=0.02)
    tool = wbc.PositionTask("arm_tool_link", gain=0.5)
    tool.set_target(start + [0.3, 0.0, 0.0])  # through the ball
    controller = wbc.Controller(robot, [tool, wbc.PostureTask(cost=1e-3)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.NonholonomicBase(),
                                 avoidance], dt=0.01)
    meshes = pin.buildGeomFromUrdf(robot.model, str(urdf), pin.GeometryType.COLLISION,
                                   package_dirs=[str(p) for p in urdf.parents])
    data, placements = robot.model.createData(), pin.GeometryData(meshes)

    def clearance(q):
        pin.forwardKinematics(robot.model, data, q)
        pin.updateGeometryPlacements(robot.model, data, meshes, placements)
        ball_pose = coal.Transform3s(np.eye(3), ball.center)
        result = np.inf
        for k, item in enumerate(meshes.geometryObjects):
            request, answer = coal.DistanceRequest(), coal.DistanceResult()
            pose = coal.Transform3s(placements.oMg[k].rotation, placements.oMg[k].translation)
            result = min(result, coal.distance(item.geometry, pose, coal.Sphere(0.05), ball_pose, request, answer))
        return result

    closest = np.inf
    for _ in range(150):
        q = robot.integrate(q, controller.step(q), controller.dt)
        closest = min(closest, clearance(q))
    assert 0.02 - 2e-3 <= closest < 0.03  # it came to the ball and kept the margin
    assert np.linalg.norm(robot.frame_pose(q, "arm_tool_link")[:3, 3] - start) > 0.05  # it moved


# ------------------------------------------------------------------ the same in a sidecar
SIDECAR = """name = "cart"
urdf = "cart.urdf"
end_effector = "tool"

[base]
kind = "differential"
lock = ["caster_joint"]
max_linear_speed = 0.5

[base.wheels]
joints = ["wheel_left_joint", "wheel_right_joint"]
"""


def test_a_sidecar_declares_the_same_base_as_the_arguments(tmp_path):
    write_robot(tmp_path)
    (tmp_path / "cart.toml").write_text(SIDECAR)
    robot = wbc.load_robot(tmp_path / "cart.urdf")  # the sidecar next to it is read
    (tmp_path / "elsewhere").mkdir()
    declared = load_quietly(write_robot(tmp_path / "elsewhere"), "differential",
                            wheels=["wheel_left_joint", "wheel_right_joint"], lock=["caster_joint"],
                            max_linear_speed=0.5)
    assert robot.base == declared.base and robot.model.names.tolist() == declared.model.names.tolist()
    assert robot.end_effector == "tool" and robot.velocity_limit[0] == 0.5


@pytest.mark.parametrize("old, new, message", [
    ('kind = "differential"', 'kind = "differential"\njoints = ["a", "b", "c"]',
     r"\[base\] joints names the model's own base joints; lock, replace and \[base.wheels\] joints"),
    ('joints = ["wheel_left_joint", "wheel_right_joint"]',
     'joints = ["wheel_left_joint", "wheel_right_joint"]\nhalf_track = 0.2',
     r"\[base.wheels\] half_track: read from the wheel joints' positions"),
    ('joints = ["wheel_left_joint", "wheel_right_joint"]', 'radius = 0.1',
     r"\[base.wheels\] half_track: required key missing"),
    ('lock = ["caster_joint"]', 'lock = ["caster"]', r"lock: 'caster' is not a joint of the model"),
])
def test_sidecar_declaration_mistakes_name_the_key(tmp_path, old, new, message):
    write_robot(tmp_path)
    (tmp_path / "cart.toml").write_text(SIDECAR.replace(old, new))
    with pytest.raises(wbc.ModelError, match=message):
        load_quietly(tmp_path / "cart.urdf")


def test_a_continuous_yaw_joint_named_as_a_base_coordinate_says_to_replace_it(tmp_path):
    write_robot(tmp_path)
    (tmp_path / "cart.toml").write_text('[base]\nkind = "planar"\njoints = ["shoulder", "elbow", "caster_joint"]\n')
    with pytest.raises(wbc.ModelError, match=r"'caster_joint' is a RUBZ joint of 2 coordinates.*replace = \[\.\.\.\]"):
        wbc.load_robot(tmp_path / "cart.urdf")


def test_speed_limits_alone_bound_the_base_the_model_has_and_never_fix_it(tmp_path):
    """``load_robot(urdf, max_linear_speed=...)`` without ``base``: a planar root stays a planar
    base with those limits (it was silently fixed at the origin before); a robot with no base to
    bound is told to declare one."""
    robot = load_quietly(write_robot(tmp_path), max_linear_speed=0.3, max_yaw_rate=0.5)
    assert robot.base.kind is wbc.BaseKind.PLANAR
    assert (robot.base.max_linear_speed, robot.base.max_yaw_rate) == (0.3, 0.5)
    fixed = tmp_path / "arm.urdf"
    fixed.write_text(PLANAR_ROBOT.format(lift=0.05, axle=0.0, track=HALF_TRACK, radius=RADIUS).replace(
        'type="planar"', 'type="fixed"'))
    with pytest.raises(wbc.ModelError, match=r"max_linear_speed bound a mobile base.*declare its base"):
        load_quietly(fixed, max_linear_speed=0.3)
