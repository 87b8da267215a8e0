"""The 3-D view (wbc.app.view, ``wbc run ... --view / --html``): what is drawn of a robot, the
self-contained HTML replay, the live viewer, and both in a real headless browser.

The browser tests (marked slow) need a Chromium-family browser (tests/browser.py finds it);
without one they skip, unless ``WBC_REQUIRE_BROWSER=1`` (CI sets it), which turns a missing
browser into a failure.
"""

import base64
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
import warnings

import numpy as np
import pinocchio as pin
import pytest

import wbc
from conftest import NEUTRAL, TASKS, require
from wbc.app.cli import main

viser = require("viser")

from browser import HeadlessBrowser, find_browser  # noqa: E402
from wbc.app import view  # noqa: E402
from wbc.app.closed_loop import run  # noqa: E402
from wbc.app.scenario import load_scenario  # noqa: E402

CIRCLE = str(TASKS / "youbot_circle.toml")


@pytest.fixture(scope="module")
def circle_run():
    """One second of the youBot circle scenario: (scenario, result)."""
    scenario = load_scenario(CIRCLE)
    return scenario, run(scenario, duration=1.0)


# ------------------------------------------------------------------ the extra and the CLI
def test_import_wbc_and_the_cli_do_not_import_viser():
    code = ("import sys, wbc, wbc.app.cli\n"
            "try:\n    wbc.app.cli.main(['run', '--help'])\nexcept SystemExit:\n    pass\n"
            "print('viser' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=NEUTRAL, timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == "False"


@pytest.mark.parametrize("options", [["--html", "out.html"], ["--view"]])
def test_missing_view_extra_fails_before_the_run(monkeypatch, tmp_path, capsys, options):
    import wbc.app.closed_loop

    def no_run(*args, **kwargs):
        raise AssertionError("the run started")

    monkeypatch.setattr(wbc.app.closed_loop, "run", no_run)
    monkeypatch.setitem(sys.modules, "viser", None)  # import viser -> ImportError
    monkeypatch.chdir(tmp_path)
    assert main(["run", CIRCLE, "--no-progress", *options]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wbc: error:") and options[0] in err and 'pip install "wbc[view]"' in err


@pytest.mark.parametrize("port", ["0", "65536"])
def test_view_port_is_checked(capsys, port):
    assert main(["run", CIRCLE, "--no-progress", "--view", port]) == 2
    assert "--view PORT must be a TCP port" in capsys.readouterr().err


def test_html_option_writes_the_replay_and_keeps_json_alone_on_stdout(tmp_path, capsys):
    page = tmp_path / "new" / "run.html"
    assert main(["run", CIRCLE, "--duration", "0.3", "--no-progress", "--json", "--html", str(page)]) == 0
    out, err = capsys.readouterr()
    assert [summary["scenario"] for summary in json.loads(out)] == ["youbot_circle"]
    assert f"3-D replay written to {page}" in err
    assert embedded_recording(page.read_text())["messages"]


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_view_option_streams_the_run_then_replays_until_interrupted():
    """``wbc run ... --view PORT``: the URL on stdout before the run, viser's client served there
    while the run streams, then the replay line after the summary; exit 0 on Ctrl-C."""
    port = free_port()
    process = subprocess.Popen([sys.executable, "-m", "wbc.app.cli", "run", CIRCLE, "--duration", "0.5",
                                "--no-progress", "--view", str(port)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, cwd=NEUTRAL)
    try:
        lines = iter(process.stdout.readline, "")
        first = next(lines, "")
        assert re.fullmatch(r"3-D view at http://127\.0\.0\.1:\d+: the run\(s\) stream live, then replay "
                            r"\(Ctrl-C to stop\)\n", first), first
        url = first.split()[3].rstrip(":")
        with urllib.request.urlopen(url, timeout=60) as response:
            assert response.status == 200 and b"<html" in response.read(2000).lower()
        rest = []
        for line in lines:
            rest.append(line)
            if line.startswith("3-D view: replaying"):
                break
        assert rest[0].startswith("scenario youbot_circle"), rest  # the summary came in between
    finally:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    assert process.returncode == 0, err
    assert "viser" not in out  # its banner is not printed


def test_ctrl_c_during_a_streamed_run_stops_it_cleanly():
    port = free_port()
    process = subprocess.Popen([sys.executable, "-m", "wbc.app.cli", "run", CIRCLE, "--no-progress", "--view",
                                str(port)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=NEUTRAL)
    try:
        assert process.stdout.readline().startswith("3-D view at ")
        time.sleep(1.0)  # the 20 s run is streaming in real time
    finally:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    assert process.returncode == 130 and err.strip().endswith("wbc: interrupted"), err
    assert "Traceback" not in err and "scenario youbot_circle" not in out  # no summary of a cut run


# ------------------------------------------------------------------------ the robot's shapes
def joint_id(robot, name: str) -> int:
    return robot.model.getJointId(name)


def test_youbot_is_its_urdf_box_plus_a_skeleton(youbot):
    shapes = view.robot_shapes(youbot)
    (box,) = [shape for shape in shapes if shape.kind == "box"]
    assert box.joint == joint_id(youbot, "base_yaw")  # the URDF's <visual> of base_link
    np.testing.assert_allclose(box.size, [0.58, 0.38, 0.1])
    np.testing.assert_allclose(box.placement[:3, 3], [0.0, 0.0, -0.05])
    assert box.colour == view.VISUAL_COLOUR  # no <material>
    bones = [shape for shape in shapes if shape.kind == "cylinder"]
    # from each arm joint to the next, and from joint 5 to the gripper tip (URDF offsets);
    # none on base_link, which has a visual, and no chassis disc
    expected = {"arm_joint_1": [0.033, 0.0, 0.147], "arm_joint_2": [0.0, 0.0, 0.155],
                "arm_joint_3": [0.0, 0.0, 0.135], "arm_joint_5": [0.0, 0.0, 0.2176]}
    assert sorted(bone.joint for bone in bones) == sorted(joint_id(youbot, name) for name in expected)
    for bone in bones:
        end = dict(zip([joint_id(youbot, n) for n in expected], expected.values(), strict=True))[bone.joint]
        radius, length = bone.size
        np.testing.assert_allclose(bone.placement @ [0, 0, -length / 2, 1], [0, 0, 0, 1], atol=1e-12)
        np.testing.assert_allclose(bone.placement @ [0, 0, length / 2, 1], [*end, 1], atol=1e-12)
        assert radius == pytest.approx(view.bone_radius(youbot))


@pytest.mark.parametrize("model", ["youbot", "deluca_mm", "scorbot_er4pc", "puma560"])
def test_skeleton_reaches_every_joint_and_the_end_effector(model, rng):
    """At a random configuration, every joint that moves something and the end-effector frame
    are at the end of a drawn bone (world positions from Pinocchio)."""
    robot = wbc.load_robot(model)
    q = robot.random_configuration(rng)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    pin.updateFramePlacements(robot.model, data)
    ends = []
    for shape in view.robot_shapes(robot):
        if shape.kind == "cylinder" and shape.colour != view.VISUAL_COLOUR:
            pose = data.oMi[shape.joint].homogeneous @ shape.placement
            ends += [(pose @ [0, 0, sign * shape.size[1] / 2, 1])[:3] for sign in (-1, 1)]
    ends = np.array(ends)

    def drawn(point):
        return np.min(np.linalg.norm(ends - point, axis=1)) < 1e-9

    assert drawn(data.oMf[robot.frame_id(robot.end_effector or "ee")].translation)
    base = {j for j in range(1, robot.model.njoints) if robot.base.is_mobile and robot.model.idx_vs[j] in
            robot.base.indices}
    for j in set(range(1, robot.model.njoints)) - base:
        assert drawn(data.oMi[j].translation), robot.model.names[j]


def test_a_mobile_base_without_visuals_gets_a_chassis_with_a_nose():
    robot = wbc.load_robot("deluca_mm")
    steering = joint_id(robot, "steering")
    chassis = [shape for shape in view.robot_shapes(robot) if shape.joint == steering]
    assert sorted(shape.kind for shape in chassis) == ["box", "cylinder"]
    nose = next(shape for shape in chassis if shape.kind == "box")
    assert nose.placement[0, 3] > 0 and nose.placement[1, 3] == 0  # ahead, along the heading


URDF = """<?xml version="1.0"?>
<robot name="shapes">
  <material name="teal"><color rgba="0 0.5 0.5 1"/></material>
  <link name="base">
    <visual><geometry><cylinder radius="0.1" length="0.4"/></geometry><material name="teal"/></visual>
  </link>
  <link name="upper">
    <visual><origin xyz="0 0 0.1"/><geometry><mesh filename="cube.stl" scale="2 2 2"/></geometry></visual>
    <visual><geometry><sphere radius="0.05"/></geometry></visual>
  </link>
  <link name="lower"/>
  <link name="tip"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="lower"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="tip_joint" type="fixed">
    <parent link="lower"/><child link="tip"/><origin xyz="0.25 0 0"/>
  </joint>
</robot>
"""


def test_urdf_primitives_materials_and_meshes(tmp_path):
    import trimesh

    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(tmp_path / "cube.stl")
    (tmp_path / "shapes.urdf").write_text(URDF)
    robot = wbc.load_robot(tmp_path / "shapes.urdf")
    shapes = view.robot_shapes(robot)
    by_kind = {kind: [s for s in shapes if s.kind == kind] for kind in ("box", "cylinder", "sphere", "mesh")}
    base = next(s for s in by_kind["cylinder"] if s.joint == 0)
    assert base.size == pytest.approx((0.1, 0.4)) and base.colour == (0, 128, 128)  # the <material>
    (mesh,) = by_kind["mesh"]
    assert mesh.joint == joint_id(robot, "shoulder") and mesh.colour == view.VISUAL_COLOUR
    np.testing.assert_allclose(mesh.vertices.max(axis=0), [0.1, 0.1, 0.1])  # 0.05 half-extent x scale 2
    np.testing.assert_allclose(mesh.placement[:3, 3], [0.0, 0.0, 0.1])
    assert any(s.joint == joint_id(robot, "shoulder") and s.size == (0.05,) for s in by_kind["sphere"])
    # "upper" has visuals: no bone of its own; "lower" has none: a bone to the tip
    bones = [s for s in by_kind["cylinder"] if s.joint != 0]
    assert [(s.joint, s.size[1]) for s in bones] == [(joint_id(robot, "elbow"), pytest.approx(0.25))]


def test_package_meshes_resolve_from_the_folders_above_the_urdf(tmp_path):
    """A ROS-style tree: share/my_robot/{urdf/robot.urdf, meshes/cube.stl}, the mesh named as
    package://my_robot/meshes/cube.stl."""
    import trimesh

    (tmp_path / "share" / "my_robot" / "meshes").mkdir(parents=True)
    (tmp_path / "share" / "my_robot" / "urdf").mkdir()
    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(tmp_path / "share" / "my_robot" / "meshes" / "cube.stl")
    urdf = tmp_path / "share" / "my_robot" / "urdf" / "robot.urdf"
    urdf.write_text(URDF.replace('filename="cube.stl"', 'filename="package://my_robot/meshes/cube.stl"'))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "visual geometry not loaded": the mesh is found
        shapes = view.robot_shapes(wbc.load_robot(urdf))
    (mesh,) = [s for s in shapes if s.kind == "mesh"]
    np.testing.assert_allclose(mesh.vertices.max(axis=0), [0.1, 0.1, 0.1])


def test_tiagos_meshes_are_drawn_on_its_declared_base():
    from test_declared_base import tiago_urdf

    robot = wbc.load_robot(tiago_urdf(), "differential", wheels=["wheel_left_joint", "wheel_right_joint"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        shapes = view.robot_shapes(robot)
    meshes = [s for s in shapes if s.kind == "mesh"]
    assert len(meshes) > 30  # tiago.urdf's <visual> elements are meshes (package://example-robot-data/...)
    heading = robot.model.getJointId("base_heading")
    assert any(s.joint == heading for s in meshes)  # the chassis rides on the declared base


def test_a_missing_mesh_falls_back_to_the_skeleton(tmp_path):
    (tmp_path / "shapes.urdf").write_text(URDF)  # cube.stl is not there
    robot = wbc.load_robot(tmp_path / "shapes.urdf")
    with pytest.warns(UserWarning, match="visual geometry not loaded"):
        shapes = view.robot_shapes(robot)
    assert {s.kind for s in shapes} == {"cylinder", "sphere"}
    assert {s.joint for s in shapes if s.kind == "cylinder"} == {0, joint_id(robot, "shoulder"),
                                                                  joint_id(robot, "elbow")}


@pytest.mark.parametrize("kind, size, pose", [
    ("cone", (1.0,), np.eye(4)), ("box", (1.0, 1.0), np.eye(4)), ("sphere", (0.0,), np.eye(4)),
    ("cylinder", (0.1, np.inf), np.eye(4)), ("sphere", (0.1,), np.eye(3)), ("sphere", (0.1,), np.full((4, 4), np.nan)),
])
def test_obstacles_are_validated(kind, size, pose):
    with pytest.raises(ValueError, match="obstacle"):
        view.Obstacle(kind, size, pose)


# ------------------------------------------------------------------------ the HTML replay
def embedded_recording(page: str) -> dict:
    """The scene recording the page embeds (viser's format: zstd-compressed msgpack, then the
    binary arrays, each 8-byte aligned; ``"buffers"`` added: those arrays as bytes)."""
    import msgspec
    import zstandard

    data = base64.b64decode(re.search(r'window\.__VISER_EMBED_DATA__="([^"]*)"', page).group(1))
    inner = zstandard.ZstdDecompressor().decompress(data[8:], max_output_size=int.from_bytes(data[:8], "little"))
    length = int.from_bytes(inner[:8], "little")
    recording = msgspec.msgpack.decode(inner[8:8 + length])
    offset, recording["buffers"] = 8 + length, []
    for size in recording["binaryBufferLengths"]:
        offset += -offset % 8
        recording["buffers"].append(inner[offset:offset + size])
        offset += size
    return recording


def array(recording: dict, placeholder: dict) -> np.ndarray:
    """The array a message refers to by a binary placeholder."""
    return np.frombuffer(recording["buffers"][placeholder["__binary_index"]], dtype=placeholder["dtype"])


def messages(recording: dict, kind: str, name: str | None = None) -> list[tuple[float, dict]]:
    return [(t, m) for t, m in recording["messages"] if m["type"] == kind and name in (None, m.get("name"))]


def test_html_replay_embeds_the_scene_and_the_recorded_trajectory(circle_run):
    scenario, result = circle_run
    obstacle = view.Obstacle("sphere", (0.1,), np.array([[1, 0, 0, 0.6], [0, 1, 0, 0.3], [0, 0, 1, 0.2], [0, 0, 0, 1]]))
    page = view.replay_html([circle_run], obstacles=[obstacle])
    assert page.lstrip().lower().startswith("<!doctype html>")
    # one document: no script, style sheet or image loaded from anywhere (inline data: only)
    assert not re.search(r"<(script|link|img|iframe)\b[^>]*\b(src|href)\s*=\s*(?![\"']?data:)", page, re.IGNORECASE)
    assert re.search(r"<link\b[^>]*\bhref\s*=\s*\"data:", page)  # the check sees attributes on several lines
    recording = embedded_recording(page)
    fps = view.FPS
    assert recording["durationSeconds"] == pytest.approx(1.0 + 1.0 / fps + 1.0)  # frames, then 1 s on the last
    (base,) = [m for _, m in messages(recording, "BoxMessage")]
    assert base["props"]["dimensions"] == pytest.approx([0.58, 0.38, 0.1])
    assert len(messages(recording, "CylinderMessage")) == 4
    (ball,) = [m for _, m in messages(recording, "IcosphereMessage", "/obstacles/0")]
    assert ball["props"]["radius"] == 0.1 and ball["props"]["opacity"] == 0.5
    # the trajectory: the gripper's joint frame follows the recorded q, frame by frame
    wrist = f"/run0/j{joint_id(scenario.robot, 'arm_joint_5')}"
    moves = messages(recording, "SetPositionMessage", wrist)
    assert len(moves) > fps * 0.9
    data = scenario.robot.model.createData()
    for t, message in moves:
        pin.forwardKinematics(scenario.robot.model, data, result.q[min(round(t / result.dt), result.time.size)])
        np.testing.assert_allclose(message["position"], data.oMi[joint_id(scenario.robot, "arm_joint_5")].translation,
                                   atol=1e-6)
    # the reference line is the reference's positions, the target follows it, the tool path
    # is revealed segment by segment, and is the recorded one
    (line,) = [m for _, m in messages(recording, "LineSegmentsMessage", "/run0/reference")]
    points = array(recording, line["props"]["points"]).reshape(-1, 2, 3)
    times = [*np.arange(0, result.time.size, round(1 / (fps * result.dt))) * result.dt, result.time.size * result.dt]
    expected = np.array([scenario.reference(t)[0][:3, 3].copy() for t in times])  # (a reused buffer)
    np.testing.assert_allclose(points[:, 0], expected[:-1], atol=1e-6)
    np.testing.assert_allclose(points[:, 1], expected[1:], atol=1e-6)
    path = [array(recording, m["props"]["points"]).reshape(-1, 2, 3)
            for _, m in messages(recording, "LineSegmentsMessage") if m["name"].startswith("/run0/path/")]
    np.testing.assert_allclose(np.concatenate(path)[:, 0], result.tool_path[:-1], atol=1e-6)
    first, last = messages(recording, "SetPositionMessage", "/run0/target")[0], messages(
        recording, "SetPositionMessage", "/run0/target")[-1]
    np.testing.assert_allclose(last[1]["position"], scenario.reference(result.time.size * result.dt)[0][:3, 3])
    assert first[0] < last[0]
    shown = messages(recording, "SetSceneNodeVisibilityMessage")
    segments = [m for _, m in shown if m["name"].startswith("/run0/path/") and m["visible"]]
    assert len(segments) == len({m["name"] for m in segments}) == len(messages(recording, "LineSegmentsMessage")) - 1


def test_several_runs_are_overlaid_in_their_own_colours(circle_run):
    reach = load_scenario(TASKS / "youbot_reach.toml")
    recording = embedded_recording(view.replay_html([circle_run, (reach, run(reach, duration=0.5))]))
    colours = {m["name"].split("/")[1]: tuple(m["props"]["color"]) for _, m in messages(recording, "CylinderMessage")}
    assert colours == {"run0": view.RUN_COLOURS[0][0], "run1": view.RUN_COLOURS[1][0]}
    ends = [t for t, _ in messages(recording, "SetPositionMessage") if _["name"].startswith("/run1/")]
    assert max(ends) == pytest.approx(0.5, abs=1.0 / view.FPS)  # the shorter run holds its last pose


def test_a_long_replay_is_played_faster_within_its_frame_budget_and_says_so(circle_run, monkeypatch):
    scenario, result = circle_run  # 1 s: 30 frames at FPS
    monkeypatch.setattr(view, "MAX_POSES", 10 * (scenario.robot.model.njoints + 1))  # 10 frames
    recording = embedded_recording(view.replay_html([circle_run]))
    wrist = f"/run0/j{joint_id(scenario.robot, 'arm_joint_5')}"
    moves = messages(recording, "SetPositionMessage", wrist)
    assert len(moves) <= 11, "at most 10 frames after the first"
    (note,) = [m for _, m in messages(recording, "LabelMessage", "/note")]
    assert note["props"]["text"] == "replayed at 3× speed"
    # frame n shows the run at 3 n / FPS s, and the page plays it in n / FPS s
    data = scenario.robot.model.createData()
    for t, message in moves:
        tick = min(round(3 * t / result.dt), result.time.size)
        pin.forwardKinematics(scenario.robot.model, data, result.q[tick])
        np.testing.assert_allclose(message["position"], data.oMi[joint_id(scenario.robot, "arm_joint_5")].translation,
                                   atol=1e-6)
    assert recording["durationSeconds"] == pytest.approx(11 / view.FPS + 1.0)


def test_a_decimated_run_is_replayed_at_its_own_pace_and_the_page_says_what_was_kept(circle_run):
    scenario, full = circle_run
    kept = run(scenario, duration=1.0, max_rows=20)  # 100 ticks, one row per 5
    assert kept.stride == 5
    recording = embedded_recording(view.replay_html([(scenario, kept)]))
    (note,) = [m for _, m in messages(recording, "LabelMessage", "/note")]
    assert note["props"]["text"] == "youbot_circle: one configuration per 5 ticks kept"
    wrist = f"/run0/j{joint_id(scenario.robot, 'arm_joint_5')}"
    moves = messages(recording, "SetPositionMessage", wrist)
    assert moves[-1][0] == pytest.approx(1.0, abs=1.5 / view.FPS), "1 s of run in 1 s of replay"
    data = scenario.robot.model.createData()
    for t, message in moves:  # the configuration of the row at t: tick 5 k, as the full run has it
        row = min(round(t / (5 * scenario.dt)), kept.time.size)
        pin.forwardKinematics(scenario.robot.model, data, full.q[5 * row] if row < kept.time.size else full.q[-1])
        np.testing.assert_allclose(message["position"], data.oMi[joint_id(scenario.robot, "arm_joint_5")].translation,
                                   atol=1e-6)


def test_write_html_refuses_a_path_before_building_the_page(circle_run, tmp_path, monkeypatch):
    from wbc.app.outputs import OutputError

    def no_page(*args, **kwargs):
        raise AssertionError("the page was built")

    monkeypatch.setattr(view, "replay_html", no_page)
    for path, message in ((tmp_path, "is a folder"), (tmp_path / "run.txt", "give a name ending in .html")):
        with pytest.raises(OutputError, match=message):
            view.write_html([circle_run], path)
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------ the live view
def test_live_view_plays_and_the_slider_pauses_it(circle_run):
    scenario, result = circle_run
    stop = threading.Event()
    with view.LiveView([circle_run], port=free_port()) as live:
        player = threading.Thread(target=live.serve, args=(stop,))
        player.start()
        try:
            wait_until(lambda: live.time.value > 0.0)  # playing
            live.time.value = 0.5  # as if the user had moved the slider
            wait_until(lambda: not live.playing.value)
            wrist = joint_id(scenario.robot, "arm_joint_5")
            frame = live.scene.tracks[0].frames[wrist]
            data = scenario.robot.model.createData()
            pin.forwardKinematics(scenario.robot.model, data, result.q[50])
            wait_until(lambda: np.allclose(frame.position, data.oMi[wrist].translation))
        finally:
            stop.set()
            player.join(timeout=60)
    assert not player.is_alive()


def test_a_slider_move_while_the_view_writes_the_time_is_not_lost(circle_run, monkeypatch):
    """The user moves the slider after the play loop looked at it and before it writes its own
    time (here: from another thread, while the scene is drawn). Before, the loop compared the
    slider with the value it read back after its write, and the move was overwritten unseen:
    playing went on (CI hit the window once)."""
    stop, moved = threading.Event(), threading.Event()
    with view.LiveView([circle_run], port=free_port()) as live:
        show = live.scene.show

        def show_then_move(t):
            show(t)
            if t > 0.0 and not moved.is_set():
                moved.set()
                user = threading.Thread(target=lambda: setattr(live.time, "value", 0.5))
                user.start()
                user.join()

        monkeypatch.setattr(live.scene, "show", show_then_move)
        player = threading.Thread(target=live.serve, args=(stop,))
        player.start()
        try:
            wait_until(lambda: moved.is_set())
            wait_until(lambda: not live.playing.value, timeout=10.0)
            wait_until(lambda: live.time.value == 0.5, timeout=10.0)
        finally:
            stop.set()
            player.join(timeout=60)
    assert not player.is_alive()


def wait_until(condition, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.05)


class FakeClock:
    """A clock that advances only when slept on: the pacing of a stream, without waiting."""

    def __init__(self) -> None:
        self.now, self.sleeps, self.on_sleep = 100.0, [], None

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += seconds
        if self.on_sleep is not None:
            self.on_sleep()


def test_a_streamed_run_is_shown_as_it_runs_and_ends_as_the_recorded_run(circle_run):
    scenario, result = circle_run
    robot, ticks = scenario.robot, result.time.size
    wrist = joint_id(robot, "arm_joint_5")
    data = robot.model.createData()
    clock = FakeClock()
    with view.LiveView([(scenario, ticks)], port=free_port()) as live:
        track = live.scene.tracks[0]
        observer = live.follow(0, clock=clock, sleep=clock.sleep)
        shown = []

        def on_tick(k, q):
            observer(k, q)
            if k % track.stride == 0:  # a frame: the robot at q[k], the tool path up to k
                pin.forwardKinematics(robot.model, data, q)
                assert np.allclose(track.frames[wrist].position, data.oMi[wrist].translation, atol=1e-12)
                assert track.shown_segments == k // track.stride
                assert live.time.value == pytest.approx(k * scenario.dt)
                shown.append(k)

        streamed = run(scenario, duration=1.0, on_tick=on_tick)
        assert live.time.disabled and "live" in live.status.content
    assert shown == list(range(track.stride, ticks + 1, track.stride))
    np.testing.assert_array_equal(streamed.q, result.q)  # streaming does not change the run
    np.testing.assert_array_equal(track.q, result.q)
    np.testing.assert_allclose(track.tool_path, result.tool_path, atol=1e-12)
    assert len(track.path_segments) == -(-ticks // track.stride)
    # held to real time: one run second of sleep in all at speed 1 (the fake clock does not move by itself)
    assert sum(clock.sleeps) == pytest.approx(ticks * scenario.dt)


def test_stream_pacing_follows_the_speed_and_does_not_make_up_a_pause(circle_run):
    scenario, result = circle_run
    clock = FakeClock()
    with view.LiveView([(scenario, result.time.size)], port=free_port()) as live:
        stride, fps = live.scene.tracks[0].stride, live.scene.fps
        live.speed.value = "2"
        observer = live.follow(0, clock=clock, sleep=clock.sleep)
        for k in range(1, 2 * stride + 1):
            observer(k, result.q[k])
        assert clock.sleeps == pytest.approx([stride * scenario.dt / 2] * 2)  # twice as fast
        clock.sleeps.clear()
        live.playing.value = False  # paused: the run waits ...

        def user():  # ... until the user ticks "play" again, 15 s later
            clock.now += 5.0
            live.playing.value = len(clock.sleeps) >= 3

        clock.on_sleep = user
        for k in range(2 * stride + 1, 3 * stride + 1):
            observer(k, result.q[k])
    # three waits of a frame each while paused, then one frame's worth of run time at speed 2:
    # the pause is not made up for by running fast after it
    assert clock.sleeps[:3] == pytest.approx([1.0 / fps] * 3)
    assert clock.sleeps[3:] == pytest.approx([stride * scenario.dt / 2])


def test_only_a_planned_run_can_be_streamed(circle_run):
    with view.LiveView([circle_run], port=free_port()) as live, pytest.raises(ValueError, match="finished run"):
        live.follow(0)


def test_closed_loop_observer_sees_every_configuration(circle_run):
    scenario, result = circle_run
    seen = []
    run(scenario, duration=1.0, on_tick=lambda k, q: seen.append((k, q.copy())))
    assert [k for k, _ in seen] == list(range(1, result.time.size + 1))
    np.testing.assert_array_equal(np.array([q for _, q in seen]), result.q[1:])


# ------------------------------------------------------------------------ in a real browser
WIDTH, HEIGHT = 900, 650
UI_BAND = 80  #: bottom pixels holding the replay's controls (their blue bar), left out of the colour counts


@pytest.fixture(scope="module")
def browser_path():
    path = find_browser()
    if path is None:
        if os.environ.get("WBC_REQUIRE_BROWSER"):
            pytest.fail("WBC_REQUIRE_BROWSER is set but no browser was found (set WBC_BROWSER or install chromium)")
        pytest.skip("no Chromium-family browser found (install chromium, or set WBC_BROWSER)")
    return path


def hue_mask(image: np.ndarray, hue: tuple[float, float], saturation: float = 0.5, value: float = 0.25) -> np.ndarray:
    """Pixels whose HSV hue [deg] lies in ``hue`` (a wrapping range if low > high), above the bounds."""
    rgb = image[:-UI_BAND].astype(float) / 255
    high, low = rgb.max(axis=2), rgb.min(axis=2)
    chroma = high - low
    with np.errstate(invalid="ignore", divide="ignore"):
        r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
        h = np.where(high == r, (g - b) / chroma % 6, np.where(high == g, (b - r) / chroma + 2, (r - g) / chroma + 4))
        h = 60 * h
        s = np.where(high > 0, chroma / high, 0)
    inside = (h >= hue[0]) & (h <= hue[1]) if hue[0] <= hue[1] else (h >= hue[0]) | (h <= hue[1])
    return inside & (s > saturation) & (high > value) & (chroma > 0)


def robot_mask(image):
    return hue_mask(image, (18, 40))  # the orange of run 0


def camera_of(recording: dict) -> dict:
    found = {}
    for _, m in recording["messages"]:
        if m["type"] == "SetCameraPositionMessage":
            found["position"] = np.array(m["position"])
        elif m["type"] == "SetCameraLookAtMessage":
            found["look_at"] = np.array(m["look_at"])
        elif m["type"] == "SetCameraFovMessage":
            found["fov"] = m["fov"]
    return found


def project(camera: dict, points: np.ndarray) -> np.ndarray:
    """Pixel (column, row) of world points seen by a pinhole camera (vertical fov, z up), as three.js draws them."""
    forward = camera["look_at"] - camera["position"]
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    d = points - camera["position"]
    depth = d @ forward
    focal = 1 / np.tan(camera["fov"] / 2)
    x = (d @ right) / depth * focal * HEIGHT / WIDTH
    y = (d @ up) / depth * focal
    return np.column_stack([(x + 1) / 2 * WIDTH, (1 - y) / 2 * HEIGHT])


def region(pixels: np.ndarray, margin: int = 40) -> tuple[slice, slice]:
    (c0, r0), (c1, r1) = pixels.min(axis=0) - margin, pixels.max(axis=0) + margin
    return slice(max(int(r0), 0), int(r1) + 1), slice(max(int(c0), 0), int(c1) + 1)


def youbot_points(robot, qs: np.ndarray) -> np.ndarray:
    """Joint origins, the gripper tip and the platform's corners over the recorded configurations."""
    data = robot.model.createData()
    corners = np.array([[x, y, z, 1] for x in (-0.29, 0.29) for y in (-0.19, 0.19) for z in (-0.1, 0.0)])
    points = []
    for q in qs:
        pin.forwardKinematics(robot.model, data, q)
        pin.updateFramePlacements(robot.model, data)
        points += [data.oMi[j].translation.copy() for j in range(1, robot.model.njoints)]  # (views into data)
        points.append(data.oMf[robot.frame_id("ee")].translation.copy())
        points += list((corners @ data.oMi[robot.model.getJointId("base_yaw")].homogeneous.T)[:, :3])
    return np.array(points)


#: viser announces software WebGL in a notification with an orange bar: hidden
NOTIFICATIONS = "[class*=Notification]"


def steady(condition):
    """A condition on screenshots that also asks for the same scene twice in a row (still and
    fully drawn: the camera and the shapes have arrived); the replay's controls may change."""
    previous = []

    def check(image):
        scene = image[:-UI_BAND]
        holds = condition(image) and bool(previous) and np.array_equal(previous[0], scene)
        previous[:] = [scene]
        return holds

    return check


def robot_shown(image) -> bool:
    return robot_mask(image).sum() > 200


@pytest.mark.slow  # a browser rendering WebGL on the CPU: 10-20 s
def test_html_replay_in_a_headless_browser(browser_path, circle_run, tmp_path):
    """The page opened from disk shows the robot where the camera puts it, the target and the
    obstacle, and requests nothing but itself and inline data."""
    scenario, result = circle_run
    obstacle_pose = np.eye(4)
    obstacle_pose[:3, 3] = [0.3, -0.6, 0.15]
    page = view.write_html([circle_run], tmp_path / "replay.html", obstacles=[view.Obstacle("box", (0.2,) * 3,
                                                                                            obstacle_pose)])
    camera = camera_of(embedded_recording(page.read_text()))
    with HeadlessBrowser(browser_path, WIDTH, HEIGHT) as browser:
        browser.open(page.as_uri())
        browser.hide(NOTIFICATIONS)
        browser.wait_for(robot_shown)
        browser.call("Input.dispatchKeyEvent", type="keyDown", code="Space", key=" ")  # pause the replay
        image = browser.wait_for(steady(robot_shown))
        urls = browser.requested_urls()
    robot = robot_mask(image)
    rows, columns = region(project(camera, youbot_points(scenario.robot, result.q)))
    inside = robot[rows, columns].sum()
    assert inside > 500 and robot.sum() - inside == 0
    targets = project(camera, np.array([scenario.reference(t)[0][:3, 3].copy() for t in result.time]))
    assert hue_mask(image, (100, 160), 0.3)[region(targets)].sum() > 50  # the green target
    obstacle = project(camera, obstacle_pose[None, :3, 3])
    assert hue_mask(image, (345, 12), 0.2)[region(obstacle, 30)].sum() > 200  # the red obstacle
    assert urls and all(url.split(":")[0] in ("file", "data", "blob") for url in urls), urls


@pytest.mark.slow  # a browser rendering WebGL on the CPU: 10-20 s
def test_html_replay_without_a_robot_shows_none(browser_path, tmp_path):
    """The control: the same page with an obstacle only has no pixel of the robot's colour."""
    page = view.write_html([], tmp_path / "empty.html", obstacles=[view.Obstacle("sphere", (0.3,))])
    with HeadlessBrowser(browser_path, WIDTH, HEIGHT) as browser:
        browser.open(page.as_uri())
        browser.hide(NOTIFICATIONS)
        image = browser.wait_for(steady(lambda image: hue_mask(image, (345, 12), 0.2).sum() > 500))
    assert robot_mask(image).sum() == 0


@pytest.mark.slow  # a browser rendering WebGL on the CPU: 10-20 s
def test_live_view_in_a_headless_browser_while_the_run_streams(browser_path):
    """The page opened while the controller runs: the robot is drawn where its streamed
    configurations put it (the stream paused half-way for a still picture)."""
    scenario = load_scenario(CIRCLE)
    ticks = 50
    with view.LiveView([(scenario, ticks)], port=free_port()) as live:
        track = live.scene.tracks[0]
        observer = live.follow(0)
        runner = threading.Thread(target=run, args=(scenario,), kwargs={"duration": ticks * scenario.dt,
                                                                        "on_tick": observer})
        runner.start()
        try:
            wait_until(lambda: track.recorded >= ticks // 2)
            live.playing.value = False  # holds the run at its next frame
            camera = {"position": live.server.initial_camera.position, "look_at": live.server.initial_camera.look_at,
                      "fov": live.server.initial_camera.fov}
            with HeadlessBrowser(browser_path, WIDTH, HEIGHT) as browser:
                browser.open(live.url)
                browser.hide(NOTIFICATIONS)
                image = browser.wait_for(steady(robot_shown))
            recorded = track.recorded
        finally:
            live.playing.value = True
            runner.join(timeout=60)
    assert not runner.is_alive() and ticks // 2 <= recorded < ticks  # the picture is mid-run
    robot = robot_mask(image)
    rows, columns = region(project(camera, youbot_points(scenario.robot, track.q[:recorded + 1])))
    assert robot[rows, columns].sum() > 500 and robot.sum() == robot[rows, columns].sum()


def test_a_scenarios_collision_obstacles_are_drawn_where_they_are():
    """Every obstacle kind of wbc.collision becomes drawn shapes at its pose (a capsule: a cylinder
    of its length and a sphere at each end; a plane: a thin square just below it)."""
    sphere, box = wbc.Sphere([0.7, 0.0, 0.1], 0.05), wbc.Box(np.eye(4), [0.2, 0.3, 0.4])
    capsule, plane = wbc.Capsule([0.0, 0.0, 0.5], [0.0, 0.6, 0.5], 0.03), wbc.Plane([-1.0, 0.0, 0.0], -1.2)
    drawn = [view.drawn_obstacle(o) for o in (sphere, box, capsule, plane)]
    (ball,), (block,), (cylinder, end0, end1), (floor,) = drawn
    assert ball.kind == "sphere" and ball.size == (0.05,) and np.allclose(ball.pose[:3, 3], [0.7, 0.0, 0.1])
    assert block.kind == "box" and block.size == (0.2, 0.3, 0.4)
    assert cylinder.kind == "cylinder" and cylinder.size == pytest.approx((0.03, 0.6))
    assert np.allclose(cylinder.pose[:3, 3], [0.0, 0.3, 0.5]) and np.allclose(np.abs(cylinder.pose[:3, 2]), [0, 1, 0])
    assert {tuple(end0.pose[:3, 3]), tuple(end1.pose[:3, 3])} == {(0.0, 0.0, 0.5), (0.0, 0.6, 0.5)}
    # the plane x = 1.2 with the free side toward -x: the square lies just beyond it, facing -x
    assert floor.kind == "box" and floor.size[2] == view.PLANE_THICKNESS
    assert np.allclose(floor.pose[:3, 3], [1.2 + view.PLANE_THICKNESS / 2, 0.0, 0.0])
    assert np.allclose(floor.pose[:3, 2], [-1.0, 0.0, 0.0])
    scenario = load_scenario("youbot_obstacle")
    kinds = sorted(o.kind for o in view.scenario_obstacles([scenario, scenario]))  # each obstacle once
    assert kinds == ["box", "box", "sphere"]  # the ball, the box beside the path, the wall (a plane)
    page = view.replay_html([], obstacles=view.scenario_obstacles([scenario]))
    (ball_message,) = [m for _, m in messages(embedded_recording(page), "IcosphereMessage")]
    assert ball_message["props"]["radius"] == 0.05
