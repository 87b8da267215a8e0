"""The node's configuration (wbc.ros.config) and the ``wbc ros`` command's entry: strict keys,
wiring that does not fit the robot named with the fix, the shipped configuration, and the
command without cyclonedds (none of this needs DDS)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

import wbc
from wbc.app.scenario import load_scenario
from wbc.ros.config import load_config, parse_config, resolve
from wbc.ros.errors import RosConfigError


@pytest.fixture(scope="module")
def youbot():
    return load_scenario("youbot_circle")


ARM = ["arm_joint_1", "arm_joint_2", "arm_joint_3", "arm_joint_4", "arm_joint_5"]


def _tables(**extra):
    return {"controllers": [{"topic": "/arm/commands", "joints": ARM}], **extra}


def test_the_shipped_youbot_configuration_fits_youbot_circle(youbot):
    config = load_config("youbot", youbot.robot, youbot.tasks)
    assert [joint.ros_name for joint in config.joints] == ARM
    assert config.odometry == "/odom" and config.base is not None and config.base.topic == "/cmd_vel"
    assert [target.topic for target in config.pose_targets] == ["/wbc/ee_target"]
    assert config.controllers[0].v_indices.tolist() == [3, 4, 5, 6, 7]
    assert config.joints[0].zero == pytest.approx(2.9496)


def test_a_folder_named_like_a_shipped_configuration_does_not_hide_it(youbot, tmp_path, monkeypatch):
    (tmp_path / "youbot").mkdir()
    monkeypatch.chdir(tmp_path)
    assert load_config("youbot", youbot.robot, youbot.tasks).odometry == "/odom"


def test_the_shipped_tiago_configuration_fits_tiago_on_its_declared_base(tmp_path):
    """config "tiago" against TIAGo's URDF (example-robot-data) on its differential base: the arm
    and torso controllers by joint order, the diff-drive command topic, the odometry."""
    from ros_harness import tiago_scenario
    from test_declared_base import tiago_urdf

    tiago_urdf()  # skips, naming the extra, where example-robot-data is not installed
    scenario = load_scenario(tiago_scenario(str(tmp_path)))
    config = load_config("tiago", scenario.robot, scenario.tasks)
    names = scenario.robot.joint_names
    assert [names[i] for c in config.controllers for i in c.v_indices] == [
        *(f"arm_{k}_joint" for k in range(1, 8)), "torso_lift_joint"]
    assert config.base is not None and config.base.topic == "/mobile_base_controller/cmd_vel_unstamped"
    assert config.odometry == "/mobile_base_controller/odom" and scenario.robot.base.kind is wbc.BaseKind.UNICYCLE


@pytest.mark.parametrize(("tables", "words"), [
    ({"state": {"timout": 0.2}}, "timout"),
    ({"state": {"timeout": "0.2"}}, "timeout"),
    ({"state": {"timeout": -1.0}}, "timeout"),
    ({"joints": {"arm_joint_1": {"sign": 2}}}, "sign"),
])
def test_malformed_tables_are_refused_naming_the_key(tables, words):
    with pytest.raises(RosConfigError, match=words):
        parse_config(_tables(**tables))


@pytest.mark.parametrize(("tables", "words"), [
    ({"controllers": [{"topic": "/arm/commands", "joints": ARM[:4]}]}, r'"arm_joint_5"\] are driven by no'),
    ({"controllers": [{"topic": "/a", "joints": ARM}, {"topic": "/b", "joints": ["arm_joint_1"]}]},
     "driven by .* too"),
    ({"controllers": [{"topic": "/arm/commands", "joints": [*ARM, "base_x"]}]}, "base coordinate"),
    (_tables(joints={"arm_joint_9": {}}), "no joint 'arm_joint_9'"),
    (_tables(targets={"poses": {"gripper": "/t"}}), "no FrameTask or PositionTask of frame or name 'gripper'"),
    (_tables(targets={"base_velocity": "/t"}), "no BaseVelocityTask"),
    (_tables(state={"odometry": "/arm/commands"}), "both topic /arm/commands"),
    (_tables(node={"namespace": "robot-1"}), "not a ROS 2 namespace"),
    (_tables(node={"world_frame": "/odom"}), "without a leading"),
])
def test_wiring_that_does_not_fit_the_robot_is_refused(youbot, tables, words):
    with pytest.raises(RosConfigError, match=words):
        resolve(parse_config(tables), youbot.robot, youbot.tasks)


def test_relative_and_private_topics_resolve_in_the_namespace(youbot):
    config = resolve(parse_config(_tables(node={"namespace": "/r1"}, state={"joint_states": "joint_states"})),
                     youbot.robot, youbot.tasks)
    assert config.joint_states == "/r1/joint_states"
    assert config.pose_targets[0].topic == "/r1/wbc/ee/target"  # the default ~/FRAME/target
    assert config.controllers[0].topic == "/arm/commands" and config.odometry is None


def test_wbc_ros_without_cyclonedds_names_the_extra(tmp_path):
    """The command imports cyclonedds only when it runs; missing, it says how to install it."""
    code = textwrap.dedent("""
        import sys
        sys.modules["cyclonedds"] = None  # as if not installed
        from wbc.app.cli import main
        status = main(["ros", "youbot_circle", "--config", "youbot"])
        print(status)
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert result.stdout.strip() == "2", result.stderr
    assert 'wbc ros needs cyclonedds, which is not installed: pip install "wbc[ros]"' in result.stderr


def test_import_wbc_and_its_cli_do_not_import_cyclonedds(tmp_path):
    code = ("import sys, wbc, wbc.app.cli; wbc.app.cli.build_parser(); "
            "print(sorted(m for m in sys.modules if 'cyclone' in m))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert result.stdout.strip() == "[]", result.stderr
