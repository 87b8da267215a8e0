"""Scenario files and model sidecars are validated strictly: every mistake is a wbc error
naming the file, the key (with its table) and the fix; nothing is silently dropped or coerced."""

import math
import shutil
from dataclasses import replace

import numpy as np
import pytest

import wbc
from conftest import ROOT, TASKS
from wbc.errors import ModelError, ScenarioError
from wbc.scenario import load_scenario

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
])
def test_mistakes_are_scenario_errors_naming_file_key_and_fix(tmp_path, old, new, expected):
    path = write(tmp_path, edited(old, new))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert message.startswith(f"{path}:"), message
    for text in expected:
        assert text in message, message


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
