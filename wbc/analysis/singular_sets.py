"""Certified singular sets of the shipped models (derivations: docs/singularities.md, tests).

A *system* is a robot, a frame and the joints that move (the columns of its 6 x n frame
Jacobian). It is singular where the Jacobian rank drops below ``min(6, n)``; the singular
set is a union of *conditions*, each an intersection of equations ``residuals(q) = 0``.
Residuals are dimensionless (lengths are divided by the system's ``length_scale``).

Adding a model is one entry in ``_BUILDERS``: a function of the loaded robot returning its
systems. A system may use only some rows of the Jacobian (``rows``, e.g. a position task)
and may be written over the real inputs of a nonholonomic base (``over_inputs``: the
columns index ``u`` of ``v = S(q) u``, :meth:`Robot.input_map`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..core.errors import ModelError
from ..model.robot import Robot

Residuals = Callable[[NDArray[np.float64]], NDArray[np.float64]]
Projection = Callable[[NDArray[np.float64]], NDArray[np.float64] | None]


@dataclass(frozen=True)
class SingularCondition:
    """One component of a singular set: all ``residuals(q)`` vanish.

    ``rank`` is the Jacobian rank at generic points of the component; ``project(q)``
    returns a configuration on the component within the joint limits, changing as few
    joints of ``q`` as it can, or ``None`` if it finds none (used to sample the set).
    """

    name: str
    formula: str
    residuals: Residuals
    rank: int
    project: Projection

    def residual(self, q: NDArray[np.float64]) -> float:
        """``max_i |residual_i(q)|`` (dimensionless)."""
        return float(np.max(np.abs(self.residuals(q))))


@dataclass(frozen=True)
class SingularSystem:
    """A robot, frame and moving joints with its certified singular conditions."""

    robot: str
    name: str
    description: str
    frame: str
    columns: tuple[int, ...]  #: velocity indices of the moving joints (columns of J)
    length_scale: float  #: L [m]: linear Jacobian rows are divided by L, prismatic columns multiplied
    conditions: tuple[SingularCondition, ...]
    rows: tuple[int, ...] = (0, 1, 2, 3, 4, 5)  #: Jacobian rows of the task (linear 0-2; angular 3-5)
    over_inputs: bool = False  #: columns index the inputs u of v = S(q) u instead of v

    @property
    def full_rank(self) -> int:
        return min(len(self.rows), len(self.columns))


def _set_angle(q: NDArray[np.float64] | None, index: int, candidates: Sequence[float], low: NDArray[np.float64],
               high: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """A copy of ``q`` with ``q[index]`` set to the angle ``candidates + 2 pi k`` inside the
    joint's limits closest to its current value; None if ``q`` is None or no candidate fits."""
    if q is None:
        return None
    best = None
    for angle in candidates:
        for k in range(-2, 3):
            value = angle + 2.0 * np.pi * k
            if low[index] <= value <= high[index] and (best is None or abs(value - q[index]) < abs(best - q[index])):
                best = value
    if best is None:
        return None
    out = q.copy()
    out[index] = best
    return out


def _geometry(robot: Robot, keys: tuple[str, ...]) -> dict[str, float]:
    geometry = robot.parameters.get("geometry", {})
    missing = [k for k in keys if k not in geometry]
    if missing:
        raise ModelError(f"robot {robot.name!r}: [geometry] of its sidecar lacks {missing}")
    return {k: float(geometry[k]) for k in keys}


# ------------------------------------------------------------------------------- youBot
def _youbot(robot: Robot) -> tuple[SingularSystem, ...]:
    """q = (X_C, Y_C, theta, theta1..theta5); ell = horizontal distance of E from axis 1."""
    g = _geometry(robot, ("a1", "a2", "a3", "c"))
    low, high = robot.lower, robot.upper
    length = g["a2"] + g["a3"] + g["c"]

    def stretched_up(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([np.sin(q[4]), np.sin(q[4] + q[5])])

    def project_stretched_up(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        out = q.copy()
        out[4:6] = 0.0
        return out

    def gripper_vertical(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([np.sin(q[4] + q[5] + q[6])])

    def project_gripper_vertical(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        return _set_angle(q, 6, [-q[4] - q[5], np.pi - q[4] - q[5]], low, high)

    def elbow(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([np.sin(q[5])])

    def project_elbow(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        return _set_angle(q, 5, [0.0, np.pi], low, high)

    def on_axis_1(q: NDArray[np.float64]) -> NDArray[np.float64]:
        t2, t23, t234 = q[4], q[4] + q[5], q[4] + q[5] + q[6]
        ell = g["a1"] + g["a2"] * np.sin(t2) + g["a3"] * np.sin(t23) + g["c"] * np.sin(t234)
        return np.array([np.sin(t234), ell / length])

    def project_on_axis_1(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        s23 = -(g["a1"] + g["a2"] * np.sin(q[4])) / g["a3"]
        if abs(s23) > 1.0:
            return None
        t23 = np.arcsin(s23)
        out = _set_angle(q, 5, [t23 - q[4], np.pi - t23 - q[4]], low, high)
        if out is None:
            return None
        t23 = out[4] + out[5]
        return _set_angle(out, 6, [-t23, np.pi - t23], low, high)

    whole_body = SingularSystem(
        robot.name, "whole_body",
        "platform (X_C, Y_C, theta) and arm, 6 x 8 geometric Jacobian of the gripper tip E",
        "ee", tuple(range(8)), length, (
            SingularCondition("links 2 and 3 vertical (Kapustina eq. 4)",
                              "sin(theta2) = 0 and sin(theta2 + theta3) = 0   (in the limits: theta2 = theta3 = 0)",
                              stretched_up, 5, project_stretched_up),
            SingularCondition("gripper axis vertical (theta_E = 0 or pi; missed by the Euler-angle Jacobian)",
                              "sin(theta2 + theta3 + theta4) = 0", gripper_vertical, 5, project_gripper_vertical),
        ))
    arm = SingularSystem(
        robot.name, "arm", "arm alone, platform fixed: 6 x 5 Jacobian of E (columns theta1..theta5)",
        "ee", tuple(range(3, 8)), length, (
            SingularCondition("elbow stretched", "sin(theta3) = 0   (in the limits: theta3 = 0)", elbow, 4,
                              project_elbow),
            SingularCondition("gripper axis vertical and on axis 1",
                              "sin(theta2 + theta3 + theta4) = 0 and "
                              "a1 + a2 sin(theta2) + a3 sin(theta2 + theta3) + c sin(theta2 + theta3 + theta4) = 0",
                              on_axis_1, 4, project_on_axis_1),
        ))
    return whole_body, arm


# ------------------------------------------------------------------------------ Scorbot
def _scorbot(robot: Robot) -> tuple[SingularSystem, ...]:
    """DH angles theta; in Gierlak's measured angles q3 - q2 = theta3, q4 = theta2 + theta3 + theta4."""
    g = _geometry(robot, ("l1", "l2", "l3", "d5"))
    low, high = robot.lower, robot.upper
    length = g["l2"] + g["l3"] + g["d5"]

    def elbow(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([np.sin(q[2])])

    def project_elbow(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        return _set_angle(q, 2, [0.0, np.pi], low, high)

    def tool_on_axis_1(q: NDArray[np.float64]) -> NDArray[np.float64]:
        q2, q3, q4 = q[1], q[1] + q[2], q[1] + q[2] + q[3]
        radius = g["l1"] + g["l2"] * np.cos(q2) + g["l3"] * np.cos(q3) + g["d5"] * np.cos(q4)
        return np.array([np.cos(q4), radius / length])

    def project_tool_on_axis_1(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        c3 = -(g["l1"] + g["l2"] * np.cos(q[1])) / g["l3"]
        if abs(c3) > 1.0:
            return None
        q3 = np.arccos(c3)
        out = _set_angle(q, 2, [q3 - q[1], -q3 - q[1]], low, high)
        if out is None:
            return None
        q3 = out[1] + out[2]
        return _set_angle(out, 3, [np.pi / 2 - q3, -np.pi / 2 - q3], low, high)

    return (SingularSystem(
        robot.name, "arm", "6 x 5 geometric Jacobian of the tool point (DH frame 5)", "ee", tuple(range(5)), length, (
            SingularCondition("elbow stretched", "sin(theta3) = sin(q3 - q2) = 0   (in the limits: theta3 = 0)",
                              elbow, 4, project_elbow),
            SingularCondition("tool axis vertical and on axis 1",
                              "cos(q4) = 0 and l1 + l2 cos(q2) + l3 cos(q3) + d5 cos(q4) = 0   "
                              "(q2 = theta2, q3 = theta2 + theta3, q4 = theta2 + theta3 + theta4)",
                              tool_on_axis_1, 4, project_tool_on_axis_1),
        )),)


# ----------------------------------------------------------------------------- PUMA 560
def _puma560(robot: Robot) -> tuple[SingularSystem, ...]:
    """det J = a2 (a3 s3 + d4 c3) (a2 c2 + a3 c23 - d4 s23) s5 (standard DH, Corke; J at the wrist centre)."""
    g = _geometry(robot, ("a2", "a3", "d3", "d4"))
    low, high = robot.lower, robot.upper
    length = g["a2"] + g["d4"]
    forearm = np.hypot(g["a3"], g["d4"])

    def wrist(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([np.sin(q[4])])

    def project_wrist(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        return _set_angle(q, 4, [0.0, np.pi], low, high)

    def elbow(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([(g["a3"] * np.sin(q[2]) + g["d4"] * np.cos(q[2])) / forearm])

    def project_elbow(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        root = np.arctan2(-g["d4"], g["a3"])
        return _set_angle(q, 2, [root, root + np.pi], low, high)

    def reach(q: NDArray[np.float64]) -> float:
        return g["a2"] * np.cos(q[1]) + g["a3"] * np.cos(q[1] + q[2]) - g["d4"] * np.sin(q[1] + q[2])

    def shoulder(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([reach(q) / length])

    def project_shoulder(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        # reach = A cos(theta2) - B sin(theta2) = rho cos(theta2 + beta)
        big_a = g["a2"] + g["a3"] * np.cos(q[2]) - g["d4"] * np.sin(q[2])
        big_b = g["a3"] * np.sin(q[2]) + g["d4"] * np.cos(q[2])
        beta = np.arctan2(big_b, big_a)
        return _set_angle(q, 1, [np.pi / 2 - beta, -np.pi / 2 - beta], low, high)

    return (SingularSystem(
        robot.name, "arm", "6 x 6 geometric Jacobian of the flange (origin at the wrist centre)", "ee",
        tuple(range(6)), length, (
            SingularCondition("wrist: axes 4 and 6 aligned", "sin(theta5) = 0   (in the limits: theta5 = 0)",
                              wrist, 5, project_wrist),
            SingularCondition("elbow: wrist centre on the line of axes 2-3 stretched",
                              "a3 sin(theta3) + d4 cos(theta3) = 0   (in the limits: theta3 = atan2(-d4, a3))",
                              elbow, 5, project_elbow),
            SingularCondition("shoulder: wrist centre in the plane of axis 1 and axis 2 (distance d3 from axis 1)",
                              "a2 cos(theta2) + a3 cos(theta2 + theta3) - d4 sin(theta2 + theta3) = 0",
                              shoulder, 5, project_shoulder),
        )),)


# ----------------------------------------------------------------------------- De Luca
def _deluca_mm(robot: Robot) -> tuple[SingularSystem, ...]:
    """p_dot = J(q) u, u = (v, omega, th1dot, th2dot, th3dot); R = l2 c2 + l3 c23 (reach).

    The 3 x 3 minors of J (its omega column is zero) are R^2 c(th - th1),
    l3 R c23 c(th - th1), -l2 l3 s3 s(th - th1) and -l2 l3 R s3; they vanish together
    exactly on the three conditions below (tests/test_singularity_deluca.py).
    """
    g = _geometry(robot, ("l2", "l3"))
    low, high = robot.lower, robot.upper
    length = g["l2"] + g["l3"]
    heading, theta1, theta2, theta3 = 2, 3, 4, 5

    def reach(q: NDArray[np.float64]) -> float:
        return (g["l2"] * np.cos(q[theta2]) + g["l3"] * np.cos(q[theta2] + q[theta3])) / length

    def project_on_axis_1(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        # R = A cos(theta2) - B sin(theta2) with A = l2 + l3 c3, B = l3 s3
        big_a = g["l2"] + g["l3"] * np.cos(q[theta3])
        big_b = g["l3"] * np.sin(q[theta3])
        beta = np.arctan2(big_b, big_a)
        return _set_angle(q, theta2, [np.pi / 2 - beta, -np.pi / 2 - beta], low, high)

    def project_stretched(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        return _set_angle(q, theta3, [0.0, np.pi], low, high)

    def steer(q: NDArray[np.float64] | None, offset: float) -> NDArray[np.float64] | None:
        if q is None:
            return None
        out = q.copy()
        out[heading] = q[theta1] + offset  # the steering angle is unbounded
        return out

    def project_double(q: NDArray[np.float64]) -> NDArray[np.float64] | None:
        stretched = project_stretched(q)
        return None if stretched is None else project_on_axis_1(stretched)

    def on_axis_1(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([reach(q)])

    def stretched(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([np.sin(q[theta3])])

    arm_conditions = (
        SingularCondition("wrist centre on axis 1", "l2 cos(theta2) + l3 cos(theta2 + theta3) = 0",
                          on_axis_1, 2, project_on_axis_1),
        SingularCondition("link 3 stretched or folded", "sin(theta3) = 0", stretched, 2, project_stretched),
    )
    whole = (
        SingularCondition("wrist centre on axis 1, wheels parallel to the arm plane",
                          "l2 cos(theta2) + l3 cos(theta2 + theta3) = 0 and sin(theta - theta1) = 0",
                          lambda q: np.array([reach(q), np.sin(q[heading] - q[theta1])]), 2,
                          lambda q: steer(project_on_axis_1(q), np.pi * (q[0] > 0))),
        SingularCondition("link 3 stretched or folded, wheels normal to the arm plane",
                          "sin(theta3) = 0 and cos(theta - theta1) = 0",
                          lambda q: np.array([np.sin(q[theta3]), np.cos(q[heading] - q[theta1])]), 2,
                          lambda q: steer(project_stretched(q), np.pi / 2 if q[0] > 0 else -np.pi / 2)),
        SingularCondition("double arm singularity (the base cannot help)",
                          "l2 cos(theta2) + l3 cos(theta2 + theta3) = 0 and sin(theta3) = 0",
                          lambda q: np.array([reach(q), np.sin(q[theta3])]), 2, project_double),
    )
    return (
        SingularSystem(robot.name, "whole_body", "3 x 5 Jacobian of the wrist centre over the inputs "
                       "u = (v, omega, theta1dot, theta2dot, theta3dot) (De Luca's J(q))", "wrist_center",
                       tuple(range(5)), length, whole, rows=(0, 1, 2), over_inputs=True),
        SingularSystem(robot.name, "arm", "arm alone: 3 x 3 Jacobian of the wrist centre (columns theta1..3)",
                       "wrist_center", (3, 4, 5), length, arm_conditions, rows=(0, 1, 2)),
    )


_BUILDERS: dict[str, Callable[[Robot], tuple[SingularSystem, ...]]] = {
    "deluca_mm": _deluca_mm,
    "youbot": _youbot,
    "scorbot_er4pc": _scorbot,
    "puma560": _puma560,
}


def registered_models() -> list[str]:
    """Names of the robots with certified singular conditions."""
    return sorted(_BUILDERS)


def singular_systems(robot: Robot) -> tuple[SingularSystem, ...]:
    """The systems of ``robot`` (the first is the default); ModelError if none are registered."""
    builder = _BUILDERS.get(robot.name)
    if builder is None:
        raise ModelError(f"no certified singular conditions for robot {robot.name!r}; "
                         f"known: {registered_models()}")
    return builder(robot)


__all__ = ["SingularCondition", "SingularSystem", "registered_models", "singular_systems"]
