"""The ROS 2 node over real DDS (no mock): the node (``wbc ros``), a simulated robot
(``python -m wbc.ros.simulated``) and an observer run as separate processes, talking through
Cyclone DDS, inside a private network namespace whose only interface is ``lo`` (``unshare
-n`` as root, ``unshare -rn`` otherwise): no DDS packet can leave the machine. Each case is
tests/ros_harness.py, run once under a timeout; the tests read its observations.

Where no private network namespace can be made the tests skip saying so, unless
``WBC_REQUIRE_SANDBOX=1`` (CI sets it), which turns that into a failure. Without cyclonedds
they skip naming the extra.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("cyclonedds", reason='the ROS 2 node needs cyclonedds: pip install "wbc[ros]"')
pytestmark = pytest.mark.slow  # ~10 s per harness run

HARNESS = Path(__file__).resolve().parent / "ros_harness.py"
TIMEOUT = 300  #: [s] for one harness run (the first start compiles numba's kernels on a fresh machine)
WATCHDOG_TIMEOUT, DT = 0.25, 0.01  #: [state] timeout of the shipped youbot configuration, youbot_circle's dt


def _namespace() -> list[str]:
    """The command prefix that runs a program in a private network namespace (skip or fail without one)."""
    attempts = []
    for unshare in (["unshare", "-n"], ["unshare", "-rn"]):
        try:
            result = subprocess.run([*unshare, "true"], capture_output=True, text=True, timeout=30)
        except FileNotFoundError as exc:
            attempts.append(str(exc))
            break
        if result.returncode == 0:
            return unshare
        attempts.append(f"{' '.join(unshare)}: exit {result.returncode}: {result.stderr.strip()[-200:]}")
    message = ("the DDS tests run only in a private network namespace (unshare -n as root, unshare -rn with "
               "unprivileged user namespaces), which cannot be made here: " + "; ".join(attempts))
    if os.environ.get("WBC_REQUIRE_SANDBOX"):
        pytest.fail(f"WBC_REQUIRE_SANDBOX is set but {message}")
    pytest.skip(message)


def _harness(case: str) -> dict:
    environment = {key: value for key, value in os.environ.items()
                   if not key.startswith(("ROS_", "CYCLONEDDS"))}  # the harness sets its own
    result = subprocess.run([*_namespace(), sys.executable, str(HARNESS), case], capture_output=True, text=True,
                            timeout=TIMEOUT, env=environment)
    assert result.returncode == 0, result.stderr[-5000:]
    return json.loads(result.stdout)


@pytest.fixture(scope="module")
def loop() -> dict:
    return _harness("loop")


@pytest.fixture(scope="module")
def integration() -> dict:
    return _harness("integration")


@pytest.fixture(scope="module")
def tiago() -> dict:
    from test_declared_base import tiago_urdf

    tiago_urdf()  # skips, naming the extra, where example-robot-data is not installed
    return _harness("tiago")


@pytest.fixture(scope="module")
def watchdog() -> dict:
    return _harness("watchdog")


@pytest.fixture(scope="module")
def fuzz() -> dict:
    return _harness("fuzz")


@pytest.mark.parametrize("case", ["loop", "integration"])
def test_closed_loop_over_dds_tracks_like_the_in_process_run(case, request):
    """youbot_circle through DDS and a robot in another process, against wbc's own kinematic
    loop over the same number of ticks: the same tracking error (every state reaching the node
    before its next tick makes the two loops the same computation) -- with the base pose from
    the robot's odometry, and from the node's own integration of its base commands."""
    from wbc.app.closed_loop import run
    from wbc.app.scenario import load_scenario

    loop = request.getfixturevalue(case)
    node = loop["node"]
    assert node["returncode"] == 0, node["stderr"]
    summary = node["output"]
    assert summary["control_ticks"] >= 200 and summary["watchdog_trips"] == 0  # (the robot starts later)
    assert summary["dropped_messages"] == 0 and summary["commands_replaced_by_zero"] == 0
    # (the observer may miss the first commands, written before discovery matched it with the node)
    assert loop["unsafe"] == [] and loop["commands"] >= 0.9 * summary["control_ticks"]
    in_process = run(load_scenario("youbot_circle"), duration=summary["control_ticks"] * DT).summary()
    print(f"{case}: position error RMS: DDS {summary['position_error_rms_m']:.6e} m, "
          f"in process {in_process['position_error_rms_m']:.6e} m; max DDS {summary['position_error_max_m']:.6e} m, "
          f"in process {in_process['position_error_max_m']:.6e} m")
    # every tick that saw the state its last command produced computes what the in-process loop does; on a
    # loaded machine a state can come late, and that tick sees the robot one tick behind the moving target.
    # The node counts the late ticks it can see (a repeated joint state); one it cannot see (a state late
    # with respect to the odometry, or the base pose integrated from a command the robot applied late) was
    # measured once under load at 1e-3 relative with none counted: the bound allows one such tick.
    print(f"{summary['repeated_state_ticks']} ticks computed from the state of the tick before")
    if summary["position_error_rms_m"] != pytest.approx(in_process["position_error_rms_m"], rel=1e-6):
        step = 2 * math.pi * 0.2 / 8.0 * DT  # [m] the circle's (radius 0.2 m, period 8 s) advance in one tick
        late = max(summary["repeated_state_ticks"], 1) / summary["control_ticks"]  # up to 3 steps off then
        # a state older than a period (measured: its writer's timestamp to the tick) puts the robot that many
        # ticks further behind the target (seen on a machine loaded by other jobs: 4.9 mm against 4.7 mm)
        behind = max(1, math.ceil(summary["state_age_max_us"] * 1e-6 / DT - 1e-9))
        print(f"oldest state taken: {summary['state_age_max_us'] * 1e-3:.1f} ms ({behind} periods)")
        bound = 3 * step * behind
        assert summary["position_error_rms_m"] <= in_process["position_error_rms_m"] + bound * math.sqrt(late)
        assert summary["position_error_max_m"] <= in_process["position_error_max_m"] + bound
    else:  # the same loop
        assert summary["position_error_max_m"] == pytest.approx(in_process["position_error_max_m"], rel=1e-6)
    robot = loop["robot"]
    # the robot applied the node's commands: under load a few are merged (two arm commands before one base
    # twist) or still in flight when the run stops (CI saw 592 steps for 601 ticks, the tracking above exact)
    assert robot["returncode"] == 0 and robot["output"]["steps"] >= 0.95 * summary["control_ticks"]


def test_tiago_on_its_differential_base_over_dds_tracks_like_the_in_process_run(tiago, tmp_path):
    """A third-party robot (TIAGo's URDF, a declared differential base, the shipped ``tiago``
    configuration: arm and torso controllers, the diff-drive's Twist, its odometry): the tool
    goes 2 m to its left through DDS as in wbc's own loop; every command on the wire is within
    the joints', the base's and the wheels' limits and has no lateral speed (the observer's
    formulas)."""
    from wbc.app.closed_loop import run
    from wbc.app.scenario import load_scenario

    node = tiago["node"]
    assert node["returncode"] == 0, node["stderr"]
    summary = node["output"]
    assert summary["control_ticks"] >= 200 and summary["watchdog_trips"] == 0
    assert summary["dropped_messages"] == 0 and summary["commands_replaced_by_zero"] == 0
    assert tiago["unsafe"] == [] and tiago["commands"] >= 0.9 * summary["control_ticks"]
    sidecar, scenario = tiago["scenario"]
    (tmp_path / "tiago.toml").write_text(sidecar)
    (tmp_path / "tiago_reach.toml").write_text(scenario)
    in_process = run(load_scenario(tmp_path / "tiago_reach.toml"), duration=summary["control_ticks"] * DT).summary()
    print(f"tiago: position error RMS: DDS {summary['position_error_rms_m']:.6e} m, "
          f"in process {in_process['position_error_rms_m']:.6e} m ({summary['repeated_state_ticks']} late ticks)")
    if summary["position_error_rms_m"] != pytest.approx(in_process["position_error_rms_m"], rel=1e-6):
        # not the same loop: only a state that came late explains it (a repeated joint state, or one
        # older than a period). One late tick sends the differential base on a slightly different
        # approach: measured +31 mm of RMS (3 %) for one repeated state, in CI and here alike (with
        # none the two runs agree to 1e-6); allowed: 5 % per late tick
        behind = max(0, math.ceil(summary["state_age_max_us"] * 1e-6 / DT - 1e-9) - 1)
        late = summary["repeated_state_ticks"] + behind
        assert late >= 1, "the DDS loop differs from the in-process one with no late state to explain it"
        ratio = summary["position_error_rms_m"] / in_process["position_error_rms_m"]
        assert 1 / (1 + 0.05 * late) <= ratio <= 1 + 0.05 * late
    # the loop itself reaches the point (over the scenario's whole duration: a loaded machine gives the
    # DDS run fewer ticks than that, CI once 362 of 600)
    assert run(load_scenario(tmp_path / "tiago_reach.toml")).summary()["final_position_error_m"] < 1e-3
    robot = tiago["robot"]
    assert robot["returncode"] == 0 and robot["output"]["steps"] >= 0.95 * summary["control_ticks"]


def test_the_startup_line_says_where_the_base_pose_comes_from(loop, integration):
    assert "base pose from odometry on /odom" in loop["node"]["stderr"]
    assert "base pose from its own integration of the base commands" in integration["node"]["stderr"]


def test_the_node_is_announced_with_its_endpoints_as_ros2_does(loop):
    """ros_discovery_info (what `ros2 node list` reads): node /wbc, its participant's GID, and the
    GIDs of its readers and writers -- each the GUID that DDS discovery reports for the node's
    endpoint on that topic."""
    graph = loop["graph"]
    (node,) = [n for n in graph["nodes"] if n["name"] == "wbc"]
    assert node["namespace"] == "/"
    endpoints, owner = graph["endpoints"], graph["participants"]
    mine = {kind: {topic: [g for g in guids if owner[g] == node["participant"]]
                   for topic, guids in endpoints[kind].items()} for kind in ("writers", "readers")}
    expected_writers = ["rt/arm_velocity_controller/commands", "rt/cmd_vel", "rt/diagnostics"]
    expected_readers = ["rt/joint_states", "rt/wbc/ee_target", "rt/odom"]
    assert sorted(node["writers"]) == sorted(mine["writers"][topic][0] for topic in expected_writers)
    assert sorted(node["readers"]) == sorted(mine["readers"][topic][0] for topic in expected_readers)


def test_diagnostics_are_published(loop):
    """diagnostic_msgs/DiagnosticArray on /diagnostics: STALE before the first state (if it came
    after the first tick), then OK
    while controlling (WARN naming them if ticks overran on a loaded machine), with the latency
    and counters as values."""
    levels = [d["level"] for d in loop["diagnostics"]]
    controlling = next((k for k, level in enumerate(levels) if level != 3), len(levels))  # OK, or WARN if it overran
    assert controlling < len(levels) and set(levels) <= {0, 1, 3} and 3 not in levels[controlling:], levels
    assert all(d["level"] == 0 or int(d["values"]["overruns"]) > 0 for d in loop["diagnostics"][controlling:])
    last = loop["diagnostics"][-1]
    overruns = int(last["values"]["overruns"])
    assert last["name"] == "/wbc" and last["message"] == ("controlling" if not overruns else f"{overruns} overruns")
    assert float(last["values"]["latency_p50_us"]) > 0 and last["values"]["dropped_messages"] == "0"


def test_killed_robot_makes_the_node_send_zero_once_and_hold(watchdog):
    assert watchdog["controlled"] and watchdog["robot_killed"] == -9
    assert watchdog["zero_after_kill"], watchdog["node"]["stderr"]
    print(f"watchdog reaction: {watchdog['reaction_s']:.3f} s after the kill (timeout {WATCHDOG_TIMEOUT} s)")
    assert watchdog["node"]["output"]["watchdog_trip_state_ages_s"][0] >= WATCHDOG_TIMEOUT  # not before
    assert watchdog["nonzero_after_zero"] == 0 and watchdog["commands_while_stale"] == 0
    assert watchdog["node"]["output"]["watchdog_trips"] == 1
    assert "watchdog: no fresh " in watchdog["node"]["stderr"]  # (joint state or odometry: both stop)


def test_fresh_states_resume_control(watchdog):
    assert watchdog["resumed"]


def test_sigint_sends_zero_within_one_tick_and_exits(watchdog):
    """After SIGINT at most the tick already under way writes its command; then the zero."""
    after = watchdog["after_sigint"]
    assert after and after[-1] is True and after.count(False) <= 1
    node = watchdog["node"]
    assert node["returncode"] == 0 and node["output"]["ticks"] > node["output"]["control_ticks"] > 0


def test_every_command_on_the_wire_is_finite_and_within_limits(loop, integration, watchdog, fuzz, tiago):
    assert loop["unsafe"] == integration["unsafe"] == watchdog["unsafe"] == fuzz["unsafe"] == tiago["unsafe"] == []


def test_sigterm_sends_zero_and_exits(fuzz):
    assert fuzz["last_is_zero"] and fuzz["node"]["returncode"] == 0


def test_fuzzed_messages_never_crash_the_node(fuzz):
    assert fuzz["controlled"] and fuzz["sent"] > 1000
    assert fuzz["alive_after_fuzz"] and fuzz["commands_after_fuzz"]
    node = fuzz["node"]
    assert node["returncode"] == 0, node["stderr"]
    assert "Traceback" not in node["stderr"] and "Warning" not in node["stderr"], node["stderr"]
    summary = node["output"]
    reasons = {key.split(": ", 1)[1] for key in summary["dropped_by_reason"]}
    print(f"fuzz: {fuzz['sent']} malformed messages sent, {summary['dropped_messages']} dropped: "
          f"{sorted(reasons)}")
    assert {"wrong array length", "duplicate name", "non-finite position", "bad stamp", "wrong frame",
            "not a unit quaternion", "non-finite pose"} <= reasons
    assert summary["dropped_messages"] == sum(summary["dropped_by_reason"].values())
    # the throttle: far fewer lines on stderr than messages dropped
    assert node["stderr"].count("dropped a message") < summary["dropped_messages"] / 5
    assert all(math.isfinite(value) for value in fuzz["robot"]["output"]["q"])
