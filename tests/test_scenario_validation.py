"""Scenario files and model sidecars are validated strictly: every mistake is a wbc error
naming the file, the key (with its table) and the fix; nothing is silently dropped or coerced."""

import math
import shutil
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

import wbc
from conftest import NEUTRAL, ROOT, TASKS
from wbc.app.scenario import load_scenario
from wbc.core.errors import ModelError, ScenarioError

CIRCLE = (TASKS / "youbot_circle.toml").read_text()


def write(tmp_path, text: str, name: str = "bad.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def edited(old: str, new: str, text: str = CIRCLE) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def test_every_shipped_scenario_loads():
    for path in sorted(TASKS.glob("*.toml")):
        scenario = load_scenario(path)
        assert scenario.tasks and scenario.constraints and type(scenario.reduced) is bool


@pytest.mark.parametrize("old, new, expected", [
    # unknown sections and keys, with a did-you-mean
    ("[[constraints]]\ntype", "[[constraint]]\ntype", ["'constraint'", "did you mean 'constraints'?"]),
    ('frame = "ee"', 'frame = "eee"', ["[[tasks]] #1 (FrameTask)", "no frame 'eee'", "did you mean ee?"]),
    ("duration = 20.0", "durration = 20.0", ["[controller]", "'durration'", "did you mean 'duration'?"]),
    ("initial_configuration", "initial_configuraton", ["[robot]", "did you mean 'initial_configuration'?"]),
    ("radius = 0.2 ", "radiu = 0.2 ", ["[reference]", "'radiu'", "did you mean 'radius'?"]),
    ('type = "circle"', 'type = "circel"', ["[reference]", "did you mean 'circle'?"]),
    # wrong types: nothing is coerced
    ("dt = 0.01", 'dt = "0.01"', ["[controller] dt", "without quotes"]),
    ("dt = 0.01", "dt = true", ["[controller] dt", "write a number"]),
    ("damping = 1e-3", 'damping = 1e-3\nreduced = "false"', ["[controller] reduced", "true or false"]),
    ("radius = 0.2 ", 'radius = "0.2" ', ["[reference] radius"]),
    # out of range
    ("duration = 20.0", "duration = -1.0", ["[controller] duration", "greater than 0"]),
    ("duration = 20.0", "duration = 0.0", ["[controller] duration", "greater than 0"]),
    ("duration = 20.0", "duration = inf", ["[controller] duration", "finite"]),
    ("duration = 20.0", "duration = nan", ["[controller] duration", "finite"]),
    ("duration = 20.0", "duration = 1e9", ["[controller]", "ticks", "shorten duration"]),
    ("dt = 0.01", "dt = 1e-12", ["[controller]", "ticks"]),
    ("dt = 0.01", "dt = 25.0", ["[controller]", "longer than duration"]),
    ("dt = 0.01", "dt = -0.01", ["[controller] dt", "greater than 0"]),
    ("radius = 0.2 ", "radius = -0.2 ", ["[reference] radius", "greater than 0"]),
    ("1.2, 0.0]", "1.2]", ["[robot] initial_configuration", "8 coordinates"]),
    # task and constraint entries
    ('type = "FrameTask"', 'type = "FrameTsk"', ["[[tasks]] #1", "did you mean 'FrameTask'?"]),
    ("gain = 0.5  ", "gian = 0.5  ", ["[[tasks]] #1 (FrameTask)", "'gian'", "did you mean 'gain'?"]),
    ("gain = 0.5  ", 'gain = "0.5"  ', ["[[tasks]] #1 (FrameTask) gain", "a finite number"]),
    ("gain = 0.5  ", "gain = 5.0  ", ["[[tasks]] #1 (FrameTask)", "(0, 1]"]),
    ("cost = 1e-3", "cost = true", ["[[tasks]] #2 (PostureTask) cost"]),
    ('target = "initial"', 'target = "inital"', ["[[tasks]] #2 (PostureTask) target", "'initial'"]),
    ('type = "MecanumWheelLimits"', 'type = "MecanumWheelLimits"\nmax_sped = 3.0',
     ["[[constraints]] #3 (MecanumWheelLimits)", "did you mean 'max_speed'?"]),
    ('type = "JointPositionLimits"\ngain = 0.5', 'type = "JointPositionLimits"\ngain = 0.0',
     ["[[constraints]] #1 (JointPositionLimits)", "gain"]),
    # files that crashed instead of erring (issue 22 §2)
    ("start_axis = [0.0, 1.0, 0.0]", "start_axis = [0.0, 0.0, 2.0]", ["[reference] (circle)", "start_axis",
                                                                      "parallel to normal"]),
    ("normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, 0.0]", ["[reference] (circle)", "normal must be a nonzero"]),
    ('type = "FrameTask"', 'type = "FrameTask"\nlevel = 1000000000', ["[[tasks]] level = 1000000000 but no task "
                                                                      "has level = 1", "without gaps"]),
    ('target = "initial"', 'target = "initial"\njoints = ["nope"]', ["[[tasks]] #2 (PostureTask)",
                                                                    "unknown joint 'nope'"]),
    ('target = "initial"', "target = [0.0, 1.0]", ["[[tasks]] #2 (PostureTask)", "target must have shape (8,)"]),
])
def test_mistakes_are_scenario_errors_naming_file_key_and_fix(tmp_path, old, new, expected):
    path = write(tmp_path, edited(old, new))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert message.startswith(f"{path}:"), message
    for text in expected:
        assert text in message, message


def test_constructor_arguments_typed_for_users_keep_their_scenario_messages(tmp_path):
    """Array-like costs take numbers or arrays (not strings); a misspelt choice of names (rows, a
    Literal for type checkers) gets the constructor's message listing the valid names, and a
    joints list (a Sequence) must be an array, as before they were annotated."""
    manipulability = '\n[[tasks]]\ntype = "ManipulabilityTask"\nframe = "ee"\ncost = 0.1\ntarget = 0.01\n'
    cases = [(CIRCLE + manipulability + 'rows = "positon"\n',
              "rows must be one of ['all', 'orientation', 'position'], got 'positon'"),
             (edited("cost = 1e-3", 'cost = "1e-3"'), "cost = '1e-3': expected a finite number or an array of numbers"),
             (edited("cost = 1e-3", 'cost = 1e-3\njoints = "arm_joint_1"'),
              "joints = 'arm_joint_1': expected an array of strings")]
    for text, message in cases:
        with pytest.raises(ScenarioError) as info:
            load_scenario(write(tmp_path, text))
        assert message in str(info.value), str(info.value)


def test_required_keys_are_required(tmp_path):
    with pytest.raises(ScenarioError, match=r"\[robot\] is missing"):
        load_scenario(write(tmp_path, edited('[robot]\nname = "youbot"', '[robot_]\nname = "youbot"')))
    with pytest.raises(ScenarioError, match=r"\[reference\] period: required key missing"):
        load_scenario(write(tmp_path, edited("period = 8.0 ", "")))
    with pytest.raises(ScenarioError, match=r"\(ManipulabilityBarrier\): required key 'min_value' missing"):
        load_scenario(write(tmp_path, CIRCLE + '\n[[constraints]]\ntype = "ManipulabilityBarrier"\nframe = "ee"\n'))


def test_planned_reference_keys_are_checked(tmp_path):
    planned = (TASKS / "puma_wrist_pass.toml").read_text()
    with pytest.raises(ScenarioError, match=r"\[reference\] reroute = 'false'.*true or false"):
        load_scenario(write(tmp_path, edited("reroute = true", 'reroute = "false"', planned)))
    with pytest.raises(ScenarioError, match=r"did you mean 'threshold'\?"):
        load_scenario(write(tmp_path, edited("threshold = 1e-4", "treshold = 1e-4", planned)))
    with pytest.raises(ScenarioError, match=r"needs centre"):
        load_scenario(write(tmp_path, edited('path = "line"', 'path = "arc"', planned)))
    wrist = 'wrist = ["joint_4", "joint_5", "joint_6"]'
    for names, count in (('["joint_4"]', "at least 3 items"), ('["joint_4", "joint_5", "joint_6", "joint_1"]',
                                                               "at most 3 items")):  # (a raw IndexError of the planner)
        with pytest.raises(ScenarioError, match=rf"\[reference\] wrist = .*list should have {count}"):
            load_scenario(write(tmp_path, edited(wrist, f"wrist = {names}", planned)))


def test_scenario_reduced_must_be_a_bool():
    scenario = load_scenario(TASKS / "youbot_circle.toml")
    with pytest.raises(ScenarioError, match="reduced"):
        replace(scenario, reduced="false")
    with pytest.raises(ScenarioError, match="dt"):
        replace(scenario, dt=math.nan)
    assert replace(scenario, reduced=True).reduced is True


def test_shipped_scenarios_build_the_same_objects():
    """The validated path builds what the old loader built: same numbers, same references."""
    scenario = load_scenario(TASKS / "youbot_circle.toml")
    assert (scenario.dt, scenario.duration, scenario.damping, scenario.solver) == (0.01, 20.0, 1e-3, "daqp")
    assert scenario.ticks == 2000
    np.testing.assert_array_equal(scenario.q0, [0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])
    position, _ = scenario.reference(2.0)
    assert position.shape == (4, 4)


# ------------------------------------------------------------------------- model sidecars
YOUBOT = (ROOT / "models" / "youbot" / "youbot.toml").read_text()


def youbot_copy(tmp_path, sidecar: str):
    """A youBot model folder in tmp_path with an edited sidecar; returns the sidecar path."""
    shutil.copy(ROOT / "models" / "youbot" / "youbot.urdf", tmp_path / "youbot.urdf")
    return write(tmp_path, sidecar, "youbot.toml")


def test_unedited_sidecar_copy_loads(tmp_path):
    robot = wbc.load_robot(youbot_copy(tmp_path, YOUBOT))
    assert robot.base.wheels.radius == 0.0475 and robot.velocity_limit[0] == 0.8


@pytest.mark.parametrize("old, new, expected", [
    ("max_linear_speed = 0.8", "max_linear_speed = -0.8", ["[base] max_linear_speed", "greater than 0"]),
    ("max_yaw_rate = 1.0", "max_yaw_rate = 0.0", ["[base] max_yaw_rate", "greater than 0"]),
    ("max_yaw_rate = 1.0", "max_yaw_rate = nan", ["[base] max_yaw_rate", "finite"]),
    ("max_yaw_rate = 1.0", 'max_yaw_rate = "1.0"', ["[base] max_yaw_rate", "without quotes"]),
    ("radius = 0.0475 ", "radius = 0.0 ", ["[base.wheels] radius", "greater than 0"]),
    ("radius = 0.0475 ", "", ["[base.wheels] radius", "required key missing"]),
    ("half_width = 0.15 ", "half_width = -0.15 ", ["[base.wheels] half_width", "greater than 0"]),
    ("max_speed = 16.842105263157894", "max_speed = inf", ["[base.wheels] max_speed", "finite"]),
    ("half_width = 0.15 ", "half_widht = 0.15 ", ["'half_widht'", "did you mean 'half_width'?"]),
    ('kind = "mecanum"', 'kind = "mecanm"', ["[base] kind = 'mecanm'", "did you mean 'mecanum'?"]),
    ("max_yaw_rate = 1.0", "max_yaw_rate = 1.0\nmax_speed = 2.0", ["[base]", "'max_speed'"]),
    ('end_effector = "ee"', 'end_efector = "ee"', ["did you mean 'end_effector'?"]),
    ('joints = ["base_x", "base_y", "base_yaw"]', 'joints = ["base_x", "base_y"]', ["[base] joints"]),
])
def test_sidecar_mistakes_are_model_errors(tmp_path, old, new, expected):
    sidecar = youbot_copy(tmp_path, edited(old, new, YOUBOT))
    with pytest.raises(ModelError) as info:
        wbc.load_robot(sidecar)
    message = str(info.value)
    assert str(sidecar) in message, message
    for text in expected:
        assert text in message, message


def test_sidecar_wheels_on_a_base_without_a_wheel_model(tmp_path):
    sidecar = youbot_copy(tmp_path, edited('kind = "mecanum"', 'kind = "planar"', YOUBOT))
    with pytest.raises(ModelError, match=r"unknown key 'wheels' in \[base\]"):
        wbc.load_robot(sidecar)


ARM = """<robot name="arm">
  <link name="root"/><link name="l1"/><link name="l2"/>
  <joint name="j1" type="revolute"><parent link="root"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1.5"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="{velocity}"/></joint>
</robot>
"""


def test_urdf_zero_velocity_limit_is_a_model_error(tmp_path):
    urdf = write(tmp_path, ARM.format(velocity="0"), "arm.urdf")
    with pytest.raises(ModelError, match=r"arm\.urdf.*'j2'.*velocity"):
        wbc.load_robot(urdf)
    good = write(tmp_path, ARM.format(velocity="2.0"), "good.urdf")
    np.testing.assert_array_equal(wbc.load_robot(good).velocity_limit, [1.5, 2.0])


def test_urdf_without_velocity_limit_is_unbounded(tmp_path):
    """A continuous joint without <limit>: Pinocchio gives inf, which wbc reads as 'no limit'."""
    urdf = write(tmp_path, ARM.format(velocity="1").replace(
        'type="revolute"><parent link="l1"', 'type="continuous"><parent link="l1"').replace(
        '<limit lower="-1" upper="1" effort="1" velocity="1"/>', ""), "free.urdf")
    robot = wbc.load_robot(urdf)
    assert robot.velocity_limit[0] == 1.5 and math.isinf(robot.velocity_limit[1])


def test_a_scenario_file_that_is_not_utf8_is_a_scenario_error(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(CIRCLE.replace('name = "youbot_circle"', 'name = "youbot_circl\xe9"').encode("latin-1"))
    with pytest.raises(ScenarioError, match=r"latin1\.toml: not UTF-8 text \(byte 0xe9 .*save it as UTF-8"):
        load_scenario(path)


def test_a_sidecar_that_is_not_utf8_is_a_model_error(tmp_path):
    sidecar = tmp_path / "youbot.toml"
    shutil.copy(ROOT / "models" / "youbot" / "youbot.urdf", tmp_path / "youbot.urdf")
    sidecar.write_bytes((YOUBOT + "# caf\xe9\n").encode("latin-1"))
    with pytest.raises(ModelError, match=r"youbot\.toml: not UTF-8 text \(byte 0xe9"):
        wbc.load_robot(sidecar)
    with pytest.raises(ModelError, match=r"not UTF-8"):
        wbc.load_robot(tmp_path / "youbot.urdf")  # the sidecar next to a URDF is read too


@pytest.mark.parametrize("joints, expected", [
    ('["base_y", "base_x", "base_yaw"]', "'base_y' (the x coordinate) must hang from the root"),
    ('["base_x", "base_x", "base_yaw"]', "names a joint twice"),
    ('["base_x", "base_y", "arm_joint_1"]', "'arm_joint_1' (the heading coordinate) must hang from 'base_y'"),
    ('["base_x", "base_yaw", "base_y"]', "'base_yaw' (the y coordinate) must hang from 'base_x'"),
])
def test_sidecar_base_joints_must_be_the_x_y_heading_joints_in_order(tmp_path, joints, expected):
    """Swapped joints loaded and gave the wrong base twist and wheel speeds, 'optimal' (issue 22 §5)."""
    sidecar = youbot_copy(tmp_path, edited('joints = ["base_x", "base_y", "base_yaw"]', f"joints = {joints}", YOUBOT))
    with pytest.raises(ModelError) as info:
        wbc.load_robot(sidecar)
    assert str(sidecar) in str(info.value) and "[base] joints" in str(info.value) and expected in str(info.value)


def test_a_sidecar_base_on_an_axis_other_than_the_world_one_is_refused(tmp_path):
    """base_x made prismatic along y in the URDF: the type matches, the axis does not."""
    sidecar = youbot_copy(tmp_path, YOUBOT)
    urdf = tmp_path / "youbot.urdf"
    text = urdf.read_text()
    start = text.index('<joint name="base_x"')
    end = text.index("</joint>", start)
    joint = text[start:end]
    assert '<axis xyz="1 0 0"/>' in joint
    urdf.write_text(text[:start] + joint.replace('<axis xyz="1 0 0"/>', '<axis xyz="0 1 0"/>') + text[end:])
    with pytest.raises(ModelError, match=r"'base_x' is the x coordinate, so it must be prismatic along world "
                                         r"\[1.0, 0.0, 0.0\]; it is prismatic along \[0.0, 1.0, 0.0\]"):
        wbc.load_robot(sidecar)


@pytest.mark.parametrize("edit, expected", [
    (('lower="-1" upper="1" effort="1" velocity="1.5"', 'lower="1" upper="-1" effort="1" velocity="1.5"'),
     r"joint 'j1' has lower limit \[1.0\] above its upper limit \[-1.0\]; swap them"),
    (('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'), r"joint 'j1' moves nothing .* unit <axis"),
])
def test_urdf_joints_that_cannot_move_are_model_errors(tmp_path, edit, expected):
    """Both loaded before: lower > upper froze the joint at v = 0 'optimal', a zero axis fed NaN to
    every tick's QP (issue 22 §5)."""
    urdf = write(tmp_path, ARM.format(velocity="1").replace(*edit), "arm.urdf")
    with pytest.raises(ModelError, match=expected):
        wbc.load_robot(urdf)


def test_a_urdf_without_joints_is_a_model_error(tmp_path):
    urdf = write(tmp_path, '<robot name="rock"><link name="root"/></robot>', "rock.urdf")
    with pytest.raises(ModelError, match="no movable joint"):
        wbc.load_robot(urdf)


def test_a_robot_too_large_for_pinocchios_data_is_refused_before_it_is_built(tmp_path):
    """Pinocchio's Data takes O(nv^3) memory (~4 GB at 400 joints); a 1000-joint chain was killed
    at 24 GB. The limit is checked on the parsed model, before any Data exists."""
    from wbc.model.robot import MAX_VELOCITY_DOF

    links = "".join(f'<link name="l{i}"/>' for i in range(MAX_VELOCITY_DOF + 2))
    joints = "".join(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i + 1}"/>'
                     f'<origin xyz="0 0 0.01"/><axis xyz="0 0 1"/>'
                     f'<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
                     for i in range(MAX_VELOCITY_DOF + 1))
    urdf = write(tmp_path, f'<robot name="snake">{links}{joints}</robot>', "snake.urdf")
    with pytest.raises(ModelError, match=rf"{MAX_VELOCITY_DOF + 1} velocity DOF; wbc handles at most "
                                         rf"{MAX_VELOCITY_DOF} .*grows as nv\^3\); with the memory for it, raise "
                                         r"wbc.model.robot.MAX_VELOCITY_DOF"):
        wbc.load_robot(urdf)


def test_every_file_is_checked_before_the_first_run_starts(tmp_path):
    """`wbc run long.toml bad.toml` ran the first file, then refused the second (an unknown
    joint is only seen when the controller is built): every file is now checked, controller
    included, before any run; one line on stderr, nothing else (no progress bar of a run)."""
    long = write(tmp_path, edited("duration = 20.0", "duration = 30.0"), "long.toml")
    bad = write(tmp_path, edited('target = "initial"', 'target = "initial"\njoints = ["nope"]'), "bad.toml")
    code = "import sys; from wbc.app.cli import main; sys.exit(main(sys.argv[1:]))"
    result = subprocess.run([sys.executable, "-c", code, "run", str(long), str(bad), "--json"], cwd=NEUTRAL,
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 2 and result.stdout == ""
    (line,) = result.stderr.splitlines()
    assert line.startswith(f"wbc: error: {bad}: [[tasks]] #2 (PostureTask)") and "unknown joint 'nope'" in line


@pytest.mark.parametrize("duration, ticks", [("1e-9", "0 ticks"), ("1e9", "100000000000 ticks")])
def test_a_duration_option_out_of_the_tick_range_is_refused_before_the_run(duration, ticks):
    """--duration 1e-9 ran 0 ticks then died in numpy; 1e9 tried to allocate 5.8 TiB (the 10^7-tick
    cap held for files only) (issue 22 §1)."""
    code = "import sys; from wbc.app.cli import main; sys.exit(main(sys.argv[1:]))"
    result = subprocess.run([sys.executable, "-c", code, "run", str(TASKS / "youbot_circle.toml"), "--duration",
                             duration, "--no-progress"], cwd=NEUTRAL, capture_output=True, text=True, timeout=600)
    assert result.returncode == 2 and result.stdout == ""
    (line,) = result.stderr.splitlines()
    assert line.startswith(f"wbc: error: --duration {float(duration):g} s is {ticks} of youbot_circle"), line
    assert "at most 1e+07" in line


@pytest.mark.parametrize("normal, start_axis", [([0.0, 0.0, 1e308], [0.0, 1.0, 0.0]),
                                                ([0.0, 0.0, 1.0], [0.0, 1e308, 1e308]),
                                                ([0.0, 0.0, 1e-6], [0.0, 2e-8, 0.0])])
def test_a_circle_takes_the_direction_of_huge_or_tiny_vectors(normal, start_axis):
    """``normal`` and ``start_axis`` are directions: 1e308 entries (whose ``np.linalg.norm`` is inf)
    and small ones give the circle of the unit vectors -- it was silently another circle (the axis
    divided by inf), with a numpy warning. Against the written-out point at t = 3 s."""
    from wbc.app.references import Circle

    start = np.eye(4)
    start[:3, 3] = (0.4, -0.1, 0.3)
    circle = Circle(start=start, radius=0.2, period=8.0, normal=np.array(normal), start_axis=np.array(start_axis),
                    ramp_time=0.0)
    a = np.array(start_axis) / np.max(np.abs(start_axis))
    a -= np.array([0.0, 0.0, 1.0]) * a[2]  # in the plane of the normal (0, 0, 1)
    a /= np.linalg.norm(a)
    b = np.cross([0.0, 0.0, 1.0], a)
    phi = 2 * np.pi * 3.0 / 8.0
    expected = start[:3, 3] - 0.2 * a + 0.2 * (np.cos(phi) * a + np.sin(phi) * b)
    np.testing.assert_allclose(circle(3.0)[0][:3, 3], expected, rtol=0, atol=1e-12)
