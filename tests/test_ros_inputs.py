"""What the node takes from the wire and writes to it, without DDS: the checks of wbc.ros.inputs
(each message built as a ROS 2 driver would send it), the last check of the commands
(wbc.ros.commands.limit_ratio, against the limits written out here) and the domain settings
read from the ROS 2 environment variables (wbc.ros.dds)."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

pytest.importorskip("cyclonedds", reason='the ROS 2 node needs cyclonedds: pip install "wbc[ros]"')

from wbc.model.robot import load_robot  # noqa: E402
from wbc.ros import messages as m  # noqa: E402
from wbc.ros.commands import limit_ratio  # noqa: E402
from wbc.ros.config import JointWiring  # noqa: E402
from wbc.ros.dds import LOOPBACK_CONFIG, domain_config, domain_id  # noqa: E402
from wbc.ros.errors import RosError  # noqa: E402
from wbc.ros.inputs import SAY_EVERY, BasePose, DropLog, JointStates, PoseTargets, TwistTargets  # noqa: E402

TIMEOUT = 0.25


def _joints() -> JointStates:
    wiring = [JointWiring("a", "robot_a", 0, 0, False, 1.0, 1.0), JointWiring("b", "robot_b", 1, 1, False, 0.0, -1.0),
              JointWiring("c", "robot_c", 2, 2, True, 0.0, 1.0)]
    return JointStates("/joint_states", wiring, TIMEOUT, DropLog(io.StringIO()))


def _state(names, positions, sec=100, nanosec=0, velocity=(), effort=()):
    return m.JointState(header=m.Header(stamp=m.Time(sec=sec, nanosec=nanosec)), name=list(names),
                        position=list(positions), velocity=list(velocity), effort=list(effort))


def test_joint_states_by_name_in_any_order_with_sign_zero_and_continuous_joints():
    states = _joints()
    assert states.accept(_state(["robot_c", "other", "robot_b", "robot_a"], [0.5, 9.0, 0.25, 3.0]), now=1.0)
    assert states.fresh(1.1)
    q = np.zeros(4)
    states.write(q)
    # q_a = +1 (3.0 - 1.0); q_b = -1 (0.25 - 0); continuous c: (cos 0.5, sin 0.5)
    assert q.tolist() == pytest.approx([2.0, -0.25, math.cos(0.5), math.sin(0.5)])


def test_joints_named_by_several_publishers_are_fresh_only_when_all_arrived():
    states = _joints()
    assert states.accept(_state(["robot_a", "robot_b"], [0.0, 0.0]), now=1.0)
    assert not states.fresh(1.01) and states.stale(1.01) == ["robot_c"]
    assert states.accept(_state(["robot_c"], [0.0]), now=1.02)
    assert states.fresh(1.03) and not states.fresh(1.0 + TIMEOUT)


@pytest.mark.parametrize(("message", "reason"), [
    (_state(["robot_a", "robot_b"], [1.0]), "wrong array length"),
    (_state(["robot_a"], [1.0], velocity=[1.0, 2.0]), "wrong array length"),
    (_state(["robot_a", "robot_a"], [1.0, 2.0]), "duplicate name"),
    (_state(["robot_a", "robot_b"], [1.0, math.nan]), "non-finite position"),
    (_state(["robot_a"], [-math.inf]), "non-finite position"),
    (_state(["robot_a"], [1.0], nanosec=1_000_000_000), "bad stamp"),
])
def test_malformed_joint_states_are_dropped_whole_and_counted(message, reason):
    states = _joints()
    assert states.accept(_state(["robot_a", "robot_b", "robot_c"], [1.5, 0.5, 0.0]), now=1.0)
    assert not states.accept(message, now=1.01)
    assert states.drops.counts == {f"/joint_states: {reason}": 1}
    q = np.zeros(4)
    states.write(q)
    assert q[:2].tolist() == [0.5, -0.5]  # the last good state kept


def test_a_stamp_going_back_is_dropped_while_fresh_and_taken_after_a_silence():
    states = _joints()
    assert states.accept(_state(["robot_a"], [1.0], sec=100), now=1.0)
    assert not states.accept(_state(["robot_a"], [2.0], sec=99), now=1.1)
    assert states.drops.counts == {"/joint_states: stamp went back": 1}
    assert states.accept(_state(["robot_a"], [2.0], sec=5), now=1.0 + TIMEOUT)  # a restarted driver
    assert states.accept(_state(["robot_a"], [2.0], sec=0), now=1.4)  # unstamped: never out of order


def test_drops_are_said_at_most_every_few_seconds_per_topic_and_reason():
    stream = io.StringIO()
    log = DropLog(stream)
    for k in range(100):
        log.drop("/t", "bad", f"number {k}", now=k * 0.01)
    log.drop("/t", "bad", "late", now=SAY_EVERY + 0.5)
    lines = stream.getvalue().splitlines()
    assert lines == ["wbc ros: dropped a message on /t: number 0",
                     "wbc ros: dropped a message on /t: late (99 more like it since)"]
    assert log.counts == {"/t: bad": 101} and log.total == 101


def _odometry(frame="odom", x=1.0, y=2.0, yaw=0.5, sec=10, quaternion=None):
    message = m.Odometry(header=m.Header(stamp=m.Time(sec=sec), frame_id=frame))
    message.pose.pose.position.x, message.pose.pose.position.y = x, y
    o = message.pose.pose.orientation
    o.x, o.y, o.z, o.w = quaternion or (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    return message


def test_odometry_gives_the_base_pose_and_drops_what_is_not_a_pose_in_the_world_frame():
    base = BasePose("/odom", "odom", TIMEOUT, DropLog(io.StringIO()))
    assert base.accept(_odometry(yaw=-2.5), now=1.0)
    assert base.pose == pytest.approx((1.0, 2.0, -2.5))
    for message in (_odometry(frame="map"), _odometry(x=math.nan), _odometry(quaternion=(0.0, 0.0, 0.0, 2.0)),
                    _odometry(quaternion=(0.0, 0.0, math.inf, 1.0)), _odometry(sec=9)):
        assert not base.accept(message, now=1.01)
    assert set(base.drops.counts) == {"/odom: wrong frame", "/odom: non-finite pose", "/odom: not a unit quaternion",
                                      "/odom: stamp went back"}
    assert base.pose == pytest.approx((1.0, 2.0, -2.5))


def test_pose_targets_become_4x4_world_poses():
    targets = PoseTargets("/t", "odom", TIMEOUT, DropLog(io.StringIO()))
    message = m.PoseStamped(header=m.Header(frame_id="odom"))
    message.pose.position.x, message.pose.position.z = 0.3, 0.4
    angle = 0.7  # about x
    message.pose.orientation.x, message.pose.orientation.w = math.sin(angle / 2), math.cos(angle / 2)
    pose = targets.pose(message, now=1.0)
    expected = np.eye(4)
    expected[1:3, 1:3] = [[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]]
    expected[:3, 3] = [0.3, 0.0, 0.4]
    assert pose == pytest.approx(expected)
    message.header.frame_id = "base_link"
    assert targets.pose(message, now=1.1) is None and targets.drops.counts == {"/t: wrong frame": 1}


def test_a_twist_target_expires_to_zero():
    twists = TwistTargets("/tw", 0.5, DropLog(io.StringIO()))
    message = m.Twist(linear=m.Vector3(x=0.1, y=-0.2), angular=m.Vector3(z=0.3))
    assert twists.twist(message, now=1.0) == (0.1, -0.2, 0.3)
    assert not twists.expired(1.49) and twists.expired(1.5)
    message.angular.z = math.nan
    assert twists.twist(message, now=1.6) is None and twists.drops.total == 1


@pytest.mark.filterwarnings("error")
def test_limit_ratio_against_the_limits_written_out():
    """youBot: |v_arm_i| / limit_i, the base-frame twist against the base limits, and each mecanum
    wheel's speed u = W^-1 (v_x, v_y, omega) against its limit -- the largest ratio."""
    robot = load_robot("youbot")
    q = np.array([0.3, -0.2, 0.9, 0.0, 0.5, 1.0, 1.2, 0.0])
    v = np.array([0.1, 0.05, 0.2, 0.5, -1.0, 0.2, 0.0, 1.4])
    yaw = q[2]
    twist = np.array([math.cos(yaw) * v[0] + math.sin(yaw) * v[1], -math.sin(yaw) * v[0] + math.cos(yaw) * v[1], v[2]])
    wheels = robot.base.wheels
    expected = max(*(abs(v[3:]) / robot.velocity_limit[3:]), *(abs(twist) / robot.velocity_limit[:3]),
                   *(abs(wheels.inverse_matrix() @ twist) / wheels.max_speed))
    assert limit_ratio(robot, q, v) == pytest.approx(expected)
    assert limit_ratio(robot, q, v * 0.0) == 0.0
    assert limit_ratio(robot, q, np.where(np.arange(8) == 4, math.nan, v)) == math.inf
    assert limit_ratio(robot, q, np.full(8, 1e308)) > 1  # huge but finite: no overflow, no warning


@pytest.mark.parametrize(("environment", "expected"), [({}, 0), ({"ROS_DOMAIN_ID": "42"}, 42),
                                                       ({"ROS_DOMAIN_ID": " "}, 0)])
def test_domain_id(environment, expected):
    assert domain_id(environment) == expected


@pytest.mark.parametrize("bad", ["-1", "233", "x", "1.5"])
def test_a_bad_domain_id_is_refused(bad):
    with pytest.raises(RosError, match="ROS_DOMAIN_ID"):
        domain_id({"ROS_DOMAIN_ID": bad})


def test_discovery_settings_follow_the_ros2_variables():
    assert domain_config({}) == ""  # SUBNET: Cyclone's defaults (multicast)
    local = domain_config({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    assert "<AllowMulticast>false</AllowMulticast>" in local and '<Peer address="localhost"/>' in local
    assert domain_config({"ROS_LOCALHOST_ONLY": "1"}) == local
    peers = domain_config({"ROS_STATIC_PEERS": "10.0.0.2; robot.local"})
    assert '<Peer address="10.0.0.2"/><Peer address="robot.local"/>' in peers and "AllowMulticast" not in peers
    assert "<Tag>" in domain_config({"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"})
    assert domain_config({"CYCLONEDDS_URI": LOOPBACK_CONFIG}) == LOOPBACK_CONFIG
    with pytest.raises(RosError, match="ROS_AUTOMATIC_DISCOVERY_RANGE"):
        domain_config({"ROS_AUTOMATIC_DISCOVERY_RANGE": "EVERYWHERE"})


def test_the_node_status_notes_each_episode_of_fallback_ticks_and_its_conflict_once():
    """NodeStatus.record_outcome (what the node's diagnostics publish): the conflicts are asked
    for at the first tick of each episode of fallback ticks only (they cost small QPs)."""
    from wbc.ros.status import NodeStatus

    status, asked = NodeStatus(), []

    def conflicts(k):
        def named():
            asked.append(k)
            return [f"Push: row {k}", "JointVelocityLimits: arm_joint_2 upper"]
        return named

    for k, success in enumerate([True, False, False, True, False, True, True]):
        status.record_outcome(success, conflicts(k))
    assert status.fallback_ticks == 3 and status.conflict_episodes == 2 and asked == [1, 4]
    assert status.last_conflicts == ["Push: row 4", "JointVelocityLimits: arm_joint_2 upper"]
    summary = status.summary({}, 0, 0)
    assert summary["conflict_episodes"] == 2 and summary["last_conflicts"][0] == "Push: row 4"
