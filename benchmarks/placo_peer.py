"""placo's side of ``wbc bench peers``: the peer stack in placo, timed tick by tick.

    PLACO_PYTHON -m benchmarks.placo_peer [INPUT.json] > OUTPUT.json   # from the checkout root

Depends on numpy, placo and :mod:`benchmarks.common` (standard library + numpy) only, never
on wbc: it runs in placo's own interpreter when placo's Pinocchio cannot share a virtual
environment with wbc's. The input (a file or standard input) is the JSON that
:func:`benchmarks.peers.placo_input` writes:

* ``stack``: ``urdf``, ``frame``, ``position_weight``, ``orientation_weight``,
  ``posture_weight``, ``posture_target`` (joint name -> value), ``regularization``,
  ``dt``, ``velocity_limits`` (joint name -> value), ``joint_names`` (the order of
  q and v in the JSON);
* ``run``: ``configurations`` (ticks x n) and ``targets`` (ticks x 4 x 4: world pose
  of the frame), ``warmup`` (ticks run first and discarded), ``closed_loop`` (bool),
  ``user_loop`` (ticks of the user's loop from ``configurations[0]``, 0: none).

Output: ``times`` (s per tick: set the target + q in + ``update_kinematics`` +
``solve(True)``, which integrates), ``commands`` (ticks x n, v = dq / dt), with
``closed_loop``: ``closed_loop_q`` (ticks x n: placo integrating its own solution from
``configurations[0]``, the configuration at the start of each tick), with ``user_loop``:
``user_loop_times`` and ``user_loop_q`` (:func:`user_loop`), and ``versions``.

The QP (:class:`PlacoStack`; conventions in benchmarks/README.md): placo adds a floating
base to every URDF; it is masked (``mask_fbase``), so the youBot's own planar joints
(base_x, base_y, base_yaw) and the 5 arm joints are the 8 unknowns, as in wbc. Every
task removes its whole error in one solve (no gain), joint limits are hard
``lower <= q + dq <= upper`` (a damper of gain 1), velocity limits ``|dq| <= dt v_max``
per coordinate, the weights multiply squared residuals in dq, and the problem's own
regularisation (1e-8 by default) is set to 0: the regularisation task is the damping.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import numpy as np

from .common import package_versions

STACK_KEYS = ("urdf", "frame", "position_weight", "orientation_weight", "posture_weight", "posture_target",
              "regularization", "dt", "velocity_limits", "joint_names")


class Peer(Protocol):
    """What a timed loop needs: a target setter, a step from q to v, and the library's own
    integration of v (placo's ``solve(True)`` integrates within ``step``)."""

    def set_target(self, pose: np.ndarray) -> None: ...

    def step(self, q: np.ndarray) -> np.ndarray: ...

    def integrate(self, q: np.ndarray, v: np.ndarray) -> object: ...


def read_input(text: str) -> tuple[dict, dict]:
    """``(stack, run)`` of an input document, arrays as float arrays; ``ValueError`` if malformed."""
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"input is not JSON: {exc}") from None
    if not isinstance(document, dict) or not {"stack", "run"} <= document.keys():
        raise ValueError("input needs the objects 'stack' and 'run'")
    stack, spec = dict(document["stack"]), dict(document["run"])
    missing = [key for key in STACK_KEYS if key not in stack]
    if missing:
        raise ValueError(f"stack lacks {', '.join(missing)}")
    names = stack["joint_names"]
    for key in ("posture_target", "velocity_limits"):
        unknown = set(stack[key]) - set(names)
        if unknown:
            raise ValueError(f"stack.{key} names joints not in joint_names: {sorted(unknown)}")
    configurations = np.asarray(spec.get("configurations", []), dtype=np.float64)
    targets = np.asarray(spec.get("targets", []), dtype=np.float64)
    ticks = len(configurations)
    if ticks == 0 or configurations.shape != (ticks, len(names)):
        raise ValueError(f"run.configurations must be (ticks, {len(names)}), got {configurations.shape}")
    if targets.shape != (ticks, 4, 4):
        raise ValueError(f"run.targets must be ({ticks}, 4, 4), got {targets.shape}")
    spec.update(configurations=configurations, targets=targets, warmup=int(spec.get("warmup", 0)),
                closed_loop=bool(spec.get("closed_loop", False)), user_loop=int(spec.get("user_loop", 0)))
    return stack, spec


class PlacoStack:
    """The peer stack as a placo ``KinematicsSolver``: frame task + joints task + regularisation
    + joint and velocity limits, on the URDF's joints only (floating base masked)."""

    def __init__(self, stack: dict, name: str = "placo") -> None:
        import placo

        self.name, self.frame = name, stack["frame"]
        self.robot = robot = placo.RobotWrapper(str(stack["urdf"]), placo.Flags.ignore_collisions)
        self.solver = solver = placo.KinematicsSolver(robot)
        solver.mask_fbase(True)
        solver.dt = self.dt = float(stack["dt"])
        solver.enable_joint_limits(True)
        solver.enable_velocity_limits(True)
        for joint, limit in stack["velocity_limits"].items():
            robot.set_velocity_limit(joint, float(limit))
        self.frame_task = solver.add_frame_task(stack["frame"], np.eye(4))
        self.frame_task.configure("frame", "soft", float(stack["position_weight"]),
                                  float(stack["orientation_weight"]))
        posture = solver.add_joints_task()
        posture.set_joints({joint: float(value) for joint, value in stack["posture_target"].items()})
        posture.configure("posture", "soft", float(stack["posture_weight"]))
        solver.add_regularization_task(float(stack["regularization"]))
        solver.problem.regularization = 0.0
        names = stack["joint_names"]
        self.q_index = np.array([robot.get_joint_offset(joint) for joint in names])
        self.v_index = np.array([robot.get_joint_v_offset(joint) for joint in names])
        self.q = np.array(robot.state.q)  # floating base at the identity, written back whole every tick

    def set_target(self, pose: np.ndarray) -> None:
        self.frame_task.T_world_frame = pose

    def step(self, q: np.ndarray) -> np.ndarray:
        """v for configuration q (q and v in ``joint_names`` order); placo integrates its own state."""
        self.q[self.q_index] = q
        self.robot.state.q = self.q
        self.robot.update_kinematics()
        return self.solver.solve(True)[self.v_index] / self.dt

    def integrate(self, q: np.ndarray, v: np.ndarray) -> None:
        """Nothing: ``step``'s ``solve(True)`` integrated placo's own state already."""


def timed_ticks(peer: Peer, configurations: np.ndarray, targets: np.ndarray,
                clock: Callable[[], float] = time.perf_counter) -> tuple[np.ndarray, np.ndarray]:
    """Wall time of ``set_target`` + ``step`` + ``integrate`` and the command, tick by tick, at the given q."""
    ticks = len(configurations)
    times, commands = np.zeros(ticks), np.zeros_like(configurations)
    for k in range(ticks):
        start = clock()
        peer.set_target(targets[k])
        q = configurations[k]
        v = peer.step(q)
        peer.integrate(q, v)
        times[k] = clock() - start
        commands[k] = v
    return times, commands


def closed_loop(stack: PlacoStack, q0: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """placo on its own: the configuration at the start of every tick, integrated by ``solve(True)``."""
    configurations = np.zeros((len(targets), q0.size))
    stack.q[stack.q_index] = q0
    stack.robot.state.q = stack.q
    for k, pose in enumerate(targets):
        configurations[k] = stack.robot.state.q[stack.q_index]
        stack.set_target(pose)
        stack.robot.update_kinematics()
        stack.solver.solve(True)
    return configurations


#: the user's loop's target: the tool's start pose moved on a horizontal circle of this radius [m]
#: and period [s], which starts at the start pose, its centre CIRCLE_RADIUS along world +y
CIRCLE_RADIUS, CIRCLE_PERIOD = 0.2, 8.0


def circle(start: np.ndarray, dt: float) -> tuple[float, float, float, float]:
    """The user's loop's circle from the frame's start pose ``start`` (4 x 4): centre x, y and
    radius [m], angle per tick [rad]; tick k's target is ``start`` moved to
    ``(cx + r sin(k a), cy - r cos(k a))`` -- written out in each loop, inside its timed part, so
    that every library's loop does the same arithmetic and no extra call."""
    return float(start[0, 3]), float(start[1, 3]) + CIRCLE_RADIUS, CIRCLE_RADIUS, 2.0 * math.pi / CIRCLE_PERIOD * dt


def user_loop(stack: PlacoStack, q0: np.ndarray, ticks: int,
              clock: Callable[[], float] = time.perf_counter) -> tuple[np.ndarray, np.ndarray]:
    """placo's loop as its user writes it, from ``q0``: the circle target computed in the loop
    (:data:`CIRCLE_RADIUS`), set, ``solve(True)`` (which integrates), ``update_kinematics()``.
    The wall time of each tick, and the configuration after it (recorded untimed).
    :func:`benchmarks.peers.wbc_user_loop` is the same loop in wbc."""
    robot, solver, task, index = stack.robot, stack.solver, stack.frame_task, stack.q_index
    stack.q[index] = q0
    robot.state.q = stack.q
    robot.update_kinematics()
    pose = np.array(robot.get_T_world_frame(stack.frame))
    (cx, cy, radius, angle_step), sin, cos = circle(pose, stack.dt), math.sin, math.cos
    times, configurations = np.zeros(ticks), np.zeros((ticks, q0.size))
    for k in range(ticks):
        start = clock()
        pose[0, 3] = cx + radius * sin(angle_step * k)
        pose[1, 3] = cy - radius * cos(angle_step * k)
        task.T_world_frame = pose
        solver.solve(True)
        robot.update_kinematics()
        times[k] = clock() - start
        configurations[k] = robot.state.q[index]
    return times, configurations


def run(stack: dict, spec: dict) -> dict:
    """Warm-up, one timed pass over the configurations of ``spec`` (the input's ``run``), optionally
    the closed loop."""
    peer = PlacoStack(stack)
    configurations, targets = spec["configurations"], spec["targets"]
    warmup = min(spec["warmup"], len(configurations))
    timed_ticks(peer, configurations[:warmup], targets[:warmup])
    times, commands = timed_ticks(peer, configurations, targets)
    out = {"times": times.tolist(), "commands": commands.tolist(),
           "versions": package_versions(["placo", "pin", "numpy"])}
    if spec["closed_loop"]:
        out["closed_loop_q"] = closed_loop(PlacoStack(stack), configurations[0], targets).tolist()
    if spec["user_loop"] > 0:
        loop = PlacoStack(stack)
        user_loop(loop, configurations[0], warmup)
        times, loop_q = user_loop(loop, configurations[0], spec["user_loop"])
        out.update(user_loop_times=times.tolist(), user_loop_q=loop_q.tolist())
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.placo_peer", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("input", nargs="?", type=Path, help="input JSON (default: standard input)")
    args = parser.parse_args(argv)
    try:
        stack, spec = read_input(args.input.read_text() if args.input else sys.stdin.read())
    except (OSError, ValueError) as exc:
        print(f"placo_peer: {exc}", file=sys.stderr)
        return 2
    json.dump(run(stack, spec), sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
