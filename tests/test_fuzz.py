"""Property-based fuzzing of ``Controller.step`` over every shipped robot and installed solver.

A *case* is a plain JSON-able dict (robot, start configuration, task and constraint specs,
solver, dt, ``reduced``, number of ticks), so that it can be rebuilt into fresh objects
(the oracle below, the shared-objects test) and run in a worker subprocess (HiGHS: its QP
solver may abort the whole process on ill-conditioned problems, which would take pytest
down with it).

Every tick of every case, in loop mode (``strict=False``), must satisfy:

1. no exception escapes ``step`` (construction may raise a ``wbc.WbcError`` whose message
   names the offending argument -- the documented rejection of bad input);
2. the command is finite, shape ``(nv,)``;
3. the hard limits hold within 1e-6 relative to the limit (at least 1e-6 absolute), checked
   here from the robot's data (README, "Mobile bases" and the Conventions table), never from
   controller internals: speed limits (base-frame ``|v_x|, |v_y|`` and ``|omega|`` for a mobile base), wheel speeds
   (``robot.wheel_speeds``) and, for nonholonomic bases, zero lateral slip -- for every
   command, optimal or fallback;
4. ``last.status`` is a non-empty string and ``last.success`` is ``status == "optimal"``;
5. when ``last.success``, the command is the QP optimum: an *independent* QP assembled in
   this file from ``robot.frame_pose`` / ``robot.frame_jacobian`` / finite differences of
   the manipulability and the README's formulas, solved by a different backend
   (quadprog, or DAQP through qpsolvers when quadprog is under test), agrees within a
   tolerance derived from H's conditioning (see :func:`check_optimum`).

Every case runs with warnings as errors (:func:`warnings_are_errors`): nothing is printed by a
tick. A case may build its controller on *copies* of its items (``case["copy"]``: ``copy.copy``,
``copy.deepcopy`` or a pickle round trip of items holding other settings, the case's own set on
the copies afterwards, through their setters), so that every property also holds for copies.

Profiles: the default (and the derandomised ``ci`` profile of conftest.py) runs ~200
examples in well under a minute. ``WBC_FUZZ_EXAMPLES=5000 pytest tests/test_fuzz.py`` or
``pytest tests/test_fuzz.py --hypothesis-profile=nightly`` runs thousands, split over the
tests in proportion to their CI shares.
"""

from __future__ import annotations

import contextlib
import copy
import json
import math
import os
import pickle
import subprocess
import sys
import tempfile
import traceback
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import qpsolvers
from hypothesis import HealthCheck, assume, currently_in_test_context, given, note, settings
from hypothesis import event as _hypothesis_event
from hypothesis import strategies as st

import wbc


def _chain24() -> wbc.Robot:
    """A 24-DOF mobile chain (benchmarks.scaling's): its controllers solve the lifted QP
    (wbc.qp.lifting) whenever at most 12 task rows are dense."""
    from conftest import ROOT

    if str(ROOT) not in sys.path:  # (the fuzz worker, a script of its own, has no conftest to append it)
        sys.path.append(str(ROOT))
    from benchmarks.scaling import chain_urdf

    folder = Path(tempfile.mkdtemp(prefix="wbc-fuzz-"))
    (folder / "chain24.urdf").write_text(chain_urdf(24))
    (folder / "chain24.toml").write_text('name = "chain24"\nurdf = "chain24.urdf"\nend_effector = "ee"\n'
                                         '[base]\nkind = "planar"\njoints = ["base_x", "base_y", "base_yaw"]\n'
                                         'max_linear_speed = 0.8\nmax_yaw_rate = 1.0\n')
    return wbc.load_robot(folder / "chain24.urdf")


ROBOT_NAMES = ["youbot", "deluca_mm", "scorbot_er4pc", "puma560", "chain24"]
ROBOTS = {name: (_chain24() if name == "chain24" else wbc.load_robot(name)) for name in ROBOT_NAMES}
SOLVERS = wbc.available_solvers()
# HiGHS can abort the interpreter (C++ assertion / std::terminate) on ill-conditioned QPs:
# its cases run in a worker subprocess (test_fuzz_highs_in_subprocess), all others in-process
SUBPROCESS_SOLVERS = {"highs"}
IN_PROCESS_SOLVERS = [s for s in SOLVERS if s not in SUBPROCESS_SOLVERS]

# Property 5 tolerance per backend: |v - v*|_inf <= max(floor, cond(H) * eps) * (1 + |v*|_inf).
# H >= damping I, so the optimum is unique and a KKT residual r moves it by <= r / lambda_min(H)
# = cond(H) r / lambda_max(H): eps is the backend's relative residual (wbc.solvers.DEFAULT_SETTINGS).
# Exact active-set methods (DAQP, quadprog, HiGHS's QP solver): eps ~ 1e-13, floor 1e-6 (the
# README's cross-solver agreement). OSQP / ProxQP (eps 1e-9 / 1e-10): floor 1e-5. Interior point
# (Clarabel, PIQP): at a degenerate optimum (a bound active with zero multiplier, e.g. a joint
# resting exactly on its limit) the error is ~ sqrt(gap), measured up to 3e-5 with the default
# 1e-12 gap: floor 1e-4. Wrong optima (wrong rows, wrong active set) are off by 1e-2 .. 1e1.
ACCURACY = {"daqp": (1e-6, 1e-13), "quadprog": (1e-6, 1e-13), "highs": (1e-6, 1e-12),
            "osqp": (1e-5, 1e-9), "proxqp": (1e-5, 1e-9), "clarabel": (1e-4, 1e-9), "piqp": (1e-4, 1e-9)}
# the cost of a command relative to the optimal cost (scale lambda_max (1 + |v*|)^2), where the
# commands themselves differ (flat directions): exact active-set and interior-point solvers
# reach ~1e-8, first-order ones (OSQP's ADMM, ProxQP's augmented Lagrangian) ~1e-5 on
# ill-conditioned stacks (seen 6e-6, ProxQP, cond(H) ~1e6); HiGHS's QP solver stops ~3e-7 short
# (a campaign of 20000 examples: 11 of 2813 HiGHS cases, cond(H) < 1e3, commands 3e-6..6e-5 apart)
COST_ACCURACY = {"osqp": 1e-5, "proxqp": 1e-5, "highs": 1e-6}
#: hard limits: 1e-6 relative to the limit, at least 1e-6 absolute (speeds in rad/s, m/s; slip in
#: m/s) -- the answer check's relative tolerance (README, "A command marked successful ..."); an
#: absolute 1e-6 failed an OSQP answer 1.7e-6 rad/s (1e-7 relative) over a 16.8 rad/s wheel limit
LIMIT_TOL = 1e-6


def beyond(value: float, limit: float) -> bool:
    """Whether ``|value|`` exceeds ``limit`` by more than :data:`LIMIT_TOL` relative."""
    return abs(value) > limit + LIMIT_TOL * max(1.0, limit)
DAMPING = 1e-3  # the Controller default; the oracle uses the same value
#: values of Controller(lm_damping=...) the cases draw: the default (twice), off, and strong
LM_DAMPINGS = [1.0, 1.0, 0.0, 10.0]


# ----------------------------------------------------------------------------- profiles
def _examples(ci: int) -> int:
    """CI example count of a test, or its share of the nightly budget.

    Nightly: ``WBC_FUZZ_EXAMPLES=N`` or ``--hypothesis-profile=nightly`` (conftest.py);
    the budget N is split over the tests in proportion to their CI counts.
    """
    if os.environ.get("WBC_FUZZ_EXAMPLES") or settings.get_current_profile_name() == "nightly":
        total = int(os.environ.get("WBC_FUZZ_EXAMPLES") or settings.get_profile("nightly").max_examples)
        return max(1, round(total * ci / CI_TOTAL))
    return ci


CI_COUNTS = {"main": 130, "highs": 20, "shared": 20}
CI_TOTAL = sum(CI_COUNTS.values())
# too_slow: an example builds a controller and solves several QPs (and the highs test pays a
# subprocess round trip); filter_too_much / data_too_large are not expected but the case
# strategy is deep, so a slow shrink should not fail the run
FUZZ_SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much,
                                                           HealthCheck.data_too_large])


@contextlib.contextmanager
def warnings_are_errors() -> Iterator[None]:
    """Every warning raised inside is an error: nothing is printed by a tick (the oracle's own
    solves say nothing either: :func:`oracle_solve`)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


def event(label: str) -> None:
    """hypothesis.event where there is a test context (not in the worker or plain tests)."""
    if currently_in_test_context():
        _hypothesis_event(label)


# ---------------------------------------------------------------------------- strategies
def log_uniform(low_exp: float, high_exp: float, edges=()):
    values = st.floats(low_exp, high_exp).map(lambda e: float(10.0 ** e))
    return st.one_of(values, st.sampled_from(list(edges))) if edges else values


COSTS = log_uniform(-12, 12, edges=(1e-12, 1e12, 1.0))
GAINS = log_uniform(-12, 0, edges=(1.0, 1e-3, 1e-12))
SPEEDS = st.one_of(st.none(), log_uniform(-3, 2))


@st.composite
def configurations(draw, robot: wbc.Robot) -> list[float]:
    """Each bounded joint inside, exactly on a limit, or up to 0.5 rad outside; the base anywhere."""
    q = np.zeros(robot.nq)
    base = set(robot.base.indices) if robot.base.is_mobile else set()
    for i in range(robot.nq):
        low, high = robot.lower[i], robot.upper[i]
        if i in base or not (np.isfinite(low) and np.isfinite(high)):
            heading = robot.base.is_mobile and i == robot.base.indices[2]
            q[i] = draw(st.floats(-4.0, 4.0) if heading else st.floats(-5.0, 5.0))
            continue
        where = draw(st.sampled_from(["inside", "inside", "lower", "upper", "below", "above"]))
        if where == "inside":
            q[i] = low + draw(st.floats(0.0, 1.0)) * (high - low)
        elif where == "lower":
            q[i] = low
        elif where == "upper":
            q[i] = high
        elif where == "below":
            q[i] = low - draw(st.floats(0.0, 0.5, exclude_min=True))
        else:
            q[i] = high + draw(st.floats(0.0, 0.5, exclude_min=True))
    return q.tolist()


@st.composite
def offsets(draw):
    """A translation near (reachable) or far (unreachable) and a rotation vector."""
    direction = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3)))
    norm = np.linalg.norm(direction)
    direction = direction / norm if norm > 1e-3 else np.array([1.0, 0.0, 0.0])
    distance = draw(st.one_of(st.just(0.0), st.floats(0.0, 0.05), st.floats(0.5, 5.0)))
    angle = draw(st.one_of(st.just(0.0), st.floats(0.0, 0.3), st.floats(0.3, 3.1)))
    axis = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3)))
    axis_norm = np.linalg.norm(axis)
    axis = axis / axis_norm if axis_norm > 1e-3 else np.array([0.0, 0.0, 1.0])
    return distance * direction, angle * axis


@st.composite
def cases(draw, solvers=None, robot_name=None):
    name = robot_name or draw(st.sampled_from(ROBOT_NAMES))
    robot = ROBOTS[name]
    q = draw(configurations(robot))
    mobile, nonholonomic = robot.base.is_mobile, robot.base.is_nonholonomic
    frame = robot.end_effector

    kinds = ["FrameTask", "PositionTask", "PostureTask", "ManipulabilityTask"]
    if mobile:
        kinds.append("BaseVelocityTask")
    if nonholonomic:
        kinds.append("SteeringTask")
    chosen = draw(st.lists(st.sampled_from(kinds), min_size=1, max_size=4))
    tasks = []
    for kind in chosen:
        if kind == "FrameTask":
            shift, rotation = draw(offsets())
            pose = robot.frame_pose(np.array(q), frame).copy()
            pose[:3, :3] = pin.exp3(rotation) @ pose[:3, :3]
            pose[:3, 3] += shift
            tasks.append(dict(kind=kind, frame=frame, position_cost=draw(COSTS), orientation_cost=draw(COSTS),
                              gain=draw(GAINS), max_speed=draw(SPEEDS), max_angular_speed=draw(SPEEDS),
                              target=pose.tolist()))
        elif kind == "PositionTask":
            shift, _ = draw(offsets())
            position = robot.frame_pose(np.array(q), frame)[:3, 3] + shift
            tasks.append(dict(kind=kind, frame=frame, cost=draw(COSTS), gain=draw(GAINS), max_speed=draw(SPEEDS),
                              target=position.tolist()))
        elif kind == "PostureTask":
            target = draw(st.one_of(st.none(), configurations(robot)))
            tasks.append(dict(kind=kind, cost=draw(COSTS), gain=draw(GAINS), target=target))
        elif kind == "BaseVelocityTask":
            twist = draw(st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3))
            tasks.append(dict(kind=kind, cost=draw(COSTS), target=twist))
        elif kind == "ManipulabilityTask":
            tasks.append(dict(kind=kind, frame=frame, cost=draw(COSTS), gain=draw(GAINS),
                              target=draw(log_uniform(-6, 0)),
                              rows=draw(st.sampled_from(["all", "position", "orientation"]))))
        elif kind == "SteeringTask":
            tasks.append(dict(kind=kind, cost=draw(COSTS), gain=draw(GAINS), speed_scale=draw(log_uniform(-3, 1))))

    reduced = draw(st.booleans()) if nonholonomic else draw(st.sampled_from([False, False, False, True]))
    constraints = []
    if draw(st.integers(0, 9)) < 7:
        constraints.append(dict(kind="JointPositionLimits", gain=draw(GAINS)))
    if draw(st.integers(0, 9)) < 8:
        constraints.append(dict(kind="JointVelocityLimits"))
    if robot.base.wheels is not None and draw(st.booleans()):
        constraints.append(dict(kind=draw(st.sampled_from(["MecanumWheelLimits", "WheelSpeedLimits"]))))
    if nonholonomic and (not reduced or draw(st.booleans())):
        # required unless reduced; left out once in a while to check the documented rejection
        if reduced or draw(st.integers(0, 19)) > 0:
            constraints.append(dict(kind="NonholonomicBase"))
    if draw(st.integers(0, 9)) < 3:
        constraints.append(dict(kind="ManipulabilityBarrier", frame=frame, min_value=draw(log_uniform(-6, -1)),
                                gain=draw(GAINS), rows=draw(st.sampled_from(["all", "position", "orientation"]))))
    constraints = draw(st.permutations(constraints))
    # strict priorities (wbc.control.hierarchy) once in four:
    # the tasks before ``levels`` at level 0, the rest at level 1
    levels = draw(st.integers(1, len(tasks) - 1)) if len(tasks) >= 2 and draw(st.integers(0, 3)) == 0 else None
    return dict(robot=name, q=q, tasks=tasks, levels=levels, constraints=constraints,
                solver=draw(st.sampled_from(solvers or IN_PROCESS_SOLVERS)),
                dt=draw(st.sampled_from([0.01, 0.01, 0.001, 0.1])), reduced=reduced,
                ticks=draw(st.integers(1, 4)), lm_damping=draw(st.sampled_from(LM_DAMPINGS)),
                copy=draw(st.sampled_from([None, None, *COPIES])))


# ----------------------------------------------------------------------------- building
class Rejected(Exception):
    """Construction refused the input with a WbcError that names the offending argument."""


def _construct(factory, **kwargs):
    """Call ``factory(**kwargs)``; a WbcError is acceptable only when it names an argument."""
    try:
        return factory(**kwargs)
    except wbc.WbcError as exc:
        if any(name in str(exc) for name in kwargs):
            raise Rejected(f"{factory.__name__}: {exc}") from exc
        raise AssertionError(f"{factory.__name__}({kwargs}) raised {exc!r}, which names none of its "
                             f"arguments {sorted(kwargs)}") from exc


def make_task(spec: dict, robot: wbc.Robot) -> wbc.Task:
    kwargs = {k: v for k, v in spec.items() if k not in ("kind", "target")}
    kind = spec["kind"]
    if kind == "PostureTask":
        target = spec["target"]
        return _construct(wbc.PostureTask, **kwargs, **({"target": np.array(target)} if target is not None else {}))
    if kind == "ManipulabilityTask":
        return _construct(wbc.ManipulabilityTask, target=spec["target"], **kwargs)
    task = _construct(getattr(wbc, kind), **kwargs)
    if kind == "FrameTask":
        task.set_target(np.array(spec["target"]))
    elif kind in ("PositionTask", "BaseVelocityTask"):
        task.set_target(np.array(spec["target"]))
    return task


def make_constraint(spec: dict) -> wbc.Constraint:
    return _construct(getattr(wbc, spec["kind"]), **{k: v for k, v in spec.items() if k != "kind"})


#: the copies a case may build its controller on (``case["copy"]``)
COPIES = {"copy": copy.copy, "deepcopy": copy.deepcopy, "pickle": lambda item: pickle.loads(pickle.dumps(item))}


def _other_value(key: str, value, spec: dict, robot: wbc.Robot):
    """A valid value of the setting ``key`` other than ``value``."""
    if key in ("cost", "position_cost", "orientation_cost"):
        return 2.0 * value + 1.0
    if key in ("max_speed", "max_angular_speed"):
        return 1.0 if value is None else None
    if key in ("gain", "min_value"):
        return value / 2.0
    if key == "speed_scale":
        return 2.0 * value
    # the target
    if spec["kind"] == "PostureTask":
        return robot.neutral() + 0.1
    if spec["kind"] == "ManipulabilityTask":
        return 2.0 * value
    if spec["kind"] == "FrameTask":
        pose = np.array(value)
        pose[:3, 3] += 0.1
        return pose
    return np.array(value) + 0.1


def apply_settings(item, spec: dict, robot: wbc.Robot, other: bool = False) -> None:
    """Set the settings of ``spec`` (the target through ``set_target``) on ``item`` through its
    setters; with ``other``, a valid value other than the spec's for each."""
    for key, value in spec.items():
        if key == "target" and key not in type(item).settings():
            if value is None:  # a posture task's: each robot's neutral configuration
                value = robot.neutral()
            item.set_target(_other_value(key, value, spec, robot) if other else np.array(value))
        elif key in type(item).settings():
            setattr(item, key, _other_value(key, value, spec, robot) if other else value)


def build(case: dict):
    """Fresh robot-bound objects and a controller for ``case``; Rejected for documented refusals.
    With ``case["copy"]`` the controller is built on copies of items that held other settings,
    and the case's settings are set on the copies afterwards."""
    robot = ROBOTS[case["robot"]]
    tasks = [make_task(spec, robot) for spec in case["tasks"]]
    constraints = [make_constraint(spec) for spec in case["constraints"]]
    duplicate = COPIES.get(case.get("copy"))
    if duplicate is not None:
        for item, spec in zip(tasks + constraints, case["tasks"] + case["constraints"], strict=True):
            apply_settings(item, spec, robot, other=True)
        tasks, constraints = [duplicate(task) for task in tasks], [duplicate(c) for c in constraints]
    needs_slip_row = (robot.base.is_nonholonomic and not case["reduced"]
                      and not any(c["kind"] == "NonholonomicBase" for c in case["constraints"]))
    split = case.get("levels")
    stack = tasks if split is None else [tasks[:split], tasks[split:]]
    try:
        controller = wbc.Controller(robot, stack, constraints, solver=case["solver"], dt=case["dt"],
                                    reduced=case["reduced"], lm_damping=case.get("lm_damping", 1.0))
    except wbc.InvalidInputError as exc:
        if needs_slip_row and "NonholonomicBase" in str(exc):
            raise Rejected(f"Controller: {exc}") from exc  # documented: required unless reduced
        raise
    assert not needs_slip_row, "a nonholonomic base without NonholonomicBase() and reduced=False was accepted"
    if duplicate is not None:  # the case's settings, on the copies the controller uses
        for item, spec in zip(tasks + constraints, case["tasks"] + case["constraints"], strict=True):
            apply_settings(item, spec, robot)
    return robot, controller


# ------------------------------------------------------------------- independent checks
def hard_limit_violations(robot: wbc.Robot, case: dict, q: np.ndarray, v: np.ndarray) -> list[str]:
    """The hard limits of README "Mobile bases" / "Tasks and constraints", from the robot's data.

    JointVelocityLimits: ``|v_i| <= velocity_limit_i`` for every non-base coordinate; for a
    mobile base the base-frame twist ``(v_x, v_y, omega) = robot.base_twist(q, v)`` obeys
    ``|v_x|, |v_y| <= max_linear_speed`` and ``|omega| <= max_yaw_rate``. Wheel limits:
    ``|robot.wheel_speeds(q, v)| <= wheels.max_speed``. Nonholonomic base (always, by the
    slip row or by ``reduced``): ``|-sin(heading) xdot + cos(heading) ydot| ~ 0``.
    """
    kinds = {c["kind"] for c in case["constraints"]}
    base = robot.base
    problems = []
    base_coords = set(base.indices) if base.is_mobile else set()
    if "JointVelocityLimits" in kinds:
        for i in range(robot.nv):
            if i not in base_coords and beyond(v[i], robot.velocity_limit[i]):
                problems.append(f"|v[{i}]| = {abs(v[i]):.9g} > {robot.velocity_limit[i]:.9g}")
        if base.is_mobile:
            vx, vy, omega = robot.base_twist(q, v)
            for label, value, limit in (("v_x", vx, base.max_linear_speed), ("v_y", vy, base.max_linear_speed),
                                        ("omega", omega, base.max_yaw_rate)):
                if beyond(value, limit):
                    problems.append(f"base |{label}| = {abs(value):.9g} > {limit:.9g}")
    if kinds & {"MecanumWheelLimits", "WheelSpeedLimits"}:
        speeds = robot.wheel_speeds(q, v)
        if beyond(np.max(np.abs(speeds)), base.wheels.max_speed):
            problems.append(f"wheel speeds {speeds} beyond {base.wheels.max_speed:.9g}")
    if base.is_nonholonomic:
        x, y, heading = base.indices
        terms = (-math.sin(q[heading]) * v[x], math.cos(q[heading]) * v[y])
        slip = sum(terms)
        # relative to its terms, as the answer check's: v = S u with |u| ~ 1e13 (no speed limits,
        # weights 1e12 at a singular pose) leaves a rounding slip of 1e-16 |u|
        if abs(slip) > LIMIT_TOL * max(1.0, abs(terms[0]) + abs(terms[1])):
            problems.append(f"lateral slip {slip:.3g} m/s")
    return problems


def _manipulability(robot, q, frame, rows):
    selected = {"all": slice(0, 6), "position": slice(0, 3), "orientation": slice(3, 6)}[rows]
    return float(np.prod(np.linalg.svd(robot.frame_jacobian(q, frame)[selected], compute_uv=False)))


def _manipulability_gradient(robot, q, frame, rows):
    """Central differences along the tangent directions (pin.integrate, as the README defines
    dm/dt = grad m . v); None where m is not smooth enough for them (near the singular set;
    on it, m = sqrt(det J J^T) = 0 has no gradient and its rounding noise ~1e-16 none either)."""
    if _manipulability(robot, q, frame, rows) < 1e-12:
        return None
    gradients = []
    for h in (1e-5, 1e-6):
        gradient = np.zeros(robot.nv)
        for i in range(robot.nv):
            step = np.zeros(robot.nv)
            step[i] = 1.0
            gradient[i] = (_manipulability(robot, robot.integrate(q, step, h), frame, rows)
                           - _manipulability(robot, robot.integrate(q, -step, h), frame, rows)) / (2 * h)
        gradients.append(gradient)
    scale = max(np.max(np.abs(gradients[0])), 1e-300)
    noise = np.max(np.abs(gradients[0] - gradients[1]))
    if noise > 1e-6 * scale:
        return None
    # entries within the differences' noise are the noise (the base x, y of an arm's m: exactly 0,
    # read as ~1e-10; a damping-only coordinate turned that into 1e-4 rad/s in the oracle's optimum)
    return np.where(np.abs(gradients[0]) > 10.0 * noise, gradients[0], 0.0)


class NotComparable(Exception):
    """The independent QP cannot be trusted here (non-smooth point, oracle solver failure)."""


def independent_qp(robot: wbc.Robot, case: dict, q: np.ndarray, damping: float = DAMPING):
    """H, c, (G, h), (A, b) of the tick at ``q`` built from the README's definitions alone.

    Cost ``sum ||W (J v - r)||^2 + max(damping, mu) ||v||^2`` -> ``H = sum (WJ)^T WJ + max(damping,
    mu) I``, ``c = -sum (WJ)^T W r`` (the 1/2 of ``1/2 v^T H v + c^T v`` absorbs the factor 2), with
    the error-scaled damping ``mu = lm_damping sum_t |dt W r_t| max_j |(W J_t) e_j|`` over the
    frame, position and manipulability tasks t (the cases have no feed-forward; Controller's
    docstring); every bound is written as a row.
    """
    nv, dt = robot.nv, case["dt"]
    base = robot.base
    rows_J, rows_r = [], []
    steering = []
    mu = 0.0

    def error_damping(WJ, Wr):  # lm_damping |dt W r| max_j |W J e_j|
        return case.get("lm_damping", 1.0) * np.linalg.norm(dt * Wr) * np.max(np.linalg.norm(WJ, axis=0))
    for spec in case["tasks"]:
        kind = spec["kind"]
        if kind in ("FrameTask", "PositionTask"):
            pose, J = robot.frame_pose(q, spec["frame"]), robot.frame_jacobian(q, spec["frame"])
            target = np.array(spec["target"])
            if kind == "FrameTask":
                error = np.r_[target[:3, 3] - pose[:3, 3], pin.log3(target[:3, :3] @ pose[:3, :3].T)]
                weights = np.r_[np.full(3, math.sqrt(spec["position_cost"])),
                                np.full(3, math.sqrt(spec["orientation_cost"]))]
                limits = (spec["max_speed"], spec["max_angular_speed"])
                if abs(np.linalg.norm(error[3:]) - math.pi) < 1e-3:
                    raise NotComparable("orientation error at pi: log3's axis is ambiguous")
            else:
                error, J = target - pose[:3, 3], J[:3]
                weights, limits = np.full(3, math.sqrt(spec["cost"])), (spec["max_speed"],)
            r = spec["gain"] / dt * error
            for part, limit in enumerate(limits):  # feedback speed bounded in norm, direction kept
                block = slice(3 * part, 3 * part + 3)
                norm = np.linalg.norm(r[block])
                if limit is not None and norm > limit:
                    r[block] *= limit / norm
            rows_J.append(weights[:, None] * J)
            rows_r.append(weights * r)
            mu += error_damping(rows_J[-1], rows_r[-1])
        elif kind == "PostureTask":
            reference = robot.neutral() if spec["target"] is None else np.array(spec["target"])
            joints = [i for i in range(nv) if not (base.is_mobile and i in base.indices)]
            J = np.eye(nv)[joints]
            w = math.sqrt(spec["cost"])
            rows_J.append(w * J)
            rows_r.append(w * spec["gain"] / dt * (reference - q)[joints])
        elif kind == "BaseVelocityTask":
            x, y, yaw = base.indices
            c, s = math.cos(q[yaw]), math.sin(q[yaw])
            J = np.zeros((3, nv))
            J[0, x], J[0, y], J[1, x], J[1, y], J[2, yaw] = c, s, -s, c, 1.0
            w = math.sqrt(spec["cost"])
            rows_J.append(w * J)
            rows_r.append(w * np.array(spec["target"]))
        elif kind == "ManipulabilityTask":
            m = _manipulability(robot, q, spec["frame"], spec["rows"])
            gradient = _manipulability_gradient(robot, q, spec["frame"], spec["rows"])
            if gradient is None:
                raise NotComparable("manipulability not smooth here")
            m_used = max(m, 1e-9 * spec["target"])
            w = math.sqrt(spec["cost"])
            rows_J.append(w * gradient[None, :] / m_used)
            rows_r.append(np.array([w * spec["gain"] / dt * math.log(spec["target"] / m_used)]))
            mu += error_damping(rows_J[-1], rows_r[-1])
        elif kind == "SteeringTask":
            steering.append(spec)
    J = np.vstack(rows_J) if rows_J else np.zeros((0, nv))
    r = np.concatenate(rows_r) if rows_r else np.zeros(0)
    H = J.T @ J + max(damping, mu) * np.eye(nv)
    c = -J.T @ r
    if steering:  # the holonomic relaxation of the other tasks (README: "Why a steering task")
        preview = np.linalg.solve(H, -c)
        x, y, heading = base.indices
        speed = math.hypot(preview[x], preview[y])
        delta = 0.0
        if speed > 0.0:
            delta = math.atan2(preview[y], preview[x]) - q[heading]
            delta = (delta + math.pi / 2) % math.pi - math.pi / 2  # forward or backward
            if abs(abs(delta) - math.pi / 2) < 1e-6:
                raise NotComparable("steering direction at the forward/backward switch")
        for spec in steering:
            weight = math.sqrt(spec["cost"]) * min(1.0, speed / spec["speed_scale"])
            H[heading, heading] += weight ** 2
            c[heading] -= weight * weight * spec["gain"] * delta / dt

    kinds = {spec["kind"] for spec in case["constraints"]}
    hard_lb, hard_ub = np.full(nv, -np.inf), np.full(nv, np.inf)
    G, h, A, b = [], [], [], []
    mobile_rows = np.zeros((3, nv))  # base-frame twist (v_x, v_y, omega) = mobile_rows v
    if base.is_mobile:
        x, y, heading = base.indices
        cos, sin = math.cos(q[heading]), math.sin(q[heading])
        mobile_rows[0, x], mobile_rows[0, y], mobile_rows[1, x], mobile_rows[1, y] = cos, sin, -sin, cos
        mobile_rows[2, heading] = 1.0
    if "JointVelocityLimits" in kinds:
        for i in range(nv):
            if not (base.is_mobile and i in base.indices[:2]):
                hard_lb[i], hard_ub[i] = -robot.velocity_limit[i], robot.velocity_limit[i]
        if base.is_mobile and np.isfinite(base.max_linear_speed):
            for row in mobile_rows[:2]:
                G += [row, -row]
                h += [base.max_linear_speed] * 2
    if kinds & {"MecanumWheelLimits", "WheelSpeedLimits"}:
        wheel_rows = base.wheels.inverse_matrix() @ mobile_rows
        G += list(wheel_rows) + list(-wheel_rows)
        h += [base.wheels.max_speed] * (2 * len(wheel_rows))
    if base.is_nonholonomic:  # the slip row, or v = S u when reduced: the same feasible set
        A.append(mobile_rows[1])
        b.append(0.0)
    lb, ub = hard_lb.copy(), hard_ub.copy()
    for spec in case["constraints"]:
        if spec["kind"] == "JointPositionLimits":  # soft bounds clipped into the hard ones
            for joint in robot.model.joints[1:]:
                i, k = joint.idx_q, joint.idx_v
                low, high = robot.lower[i], robot.upper[i]
                if not (np.isfinite(low) or np.isfinite(high)):
                    continue
                # README: the fraction gain of each margin inside the limits, the full margins outside
                scale = spec["gain"] if low <= q[i] <= high else 1.0
                soft_low, soft_high = scale * (low - q[i]) / dt, scale * (high - q[i]) / dt
                lb[k] = min(max(soft_low, hard_lb[k]), hard_ub[k])
                ub[k] = min(max(soft_high, hard_lb[k]), hard_ub[k])
        elif spec["kind"] == "ManipulabilityBarrier":
            m = _manipulability(robot, q, spec["frame"], spec["rows"])
            gradient = _manipulability_gradient(robot, q, spec["frame"], spec["rows"])
            if gradient is None:
                raise NotComparable("manipulability not smooth here")
            G.append(-gradient)
            h.append(spec["gain"] * (m - spec["min_value"]) / dt)
    for i in range(nv):
        if np.isfinite(ub[i]):
            G.append(np.eye(nv)[i])
            h.append(ub[i])
        if np.isfinite(lb[i]):
            G.append(-np.eye(nv)[i])
            h.append(-lb[i])
    G = np.array(G).reshape(-1, nv)
    A = np.array(A).reshape(-1, nv)
    return H, c, G, np.array(h), A, np.array(b)


def oracle_solve(problem: qpsolvers.Problem, solver: str) -> qpsolvers.Solution:
    """The oracle's solve of ``problem`` by ``solver`` through qpsolvers, without the UserWarnings
    qpsolvers issues about it: this file's dense matrices converted for a sparse backend, an
    unconstrained QP sent to SciPy's LSQR instead of Clarabel, Clarabel's "AlmostSolved" or
    "InsufficientProgress" (the oracle's business: its answer is checked like any other, and
    discarded if wrong). wbc's own backends are silent (wbc.solvers)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=UserWarning, module="qpsolvers")
        return qpsolvers.solve_problem(problem, solver=solver)


def normalised_problem(H, c, G, h, A, b, curvature: float) -> qpsolvers.Problem:
    """The QP ``min 1/2 v^T H v + c^T v`` over the rows, its cost divided by ``curvature`` (H's
    largest eigenvalue): the same minimiser, in the scale the backends' absolute tolerances are
    made for. (Unscaled, quadprog called a youBot level weighted 1.8e9 "inconsistent" and the
    oracle fell back to Clarabel, whose answer was 1.5e-4 rad/s from the exact optimum: fuzz seed 31.)"""
    scale = 1.0 / curvature if curvature > 0.0 else 1.0
    return qpsolvers.Problem(H * scale, c * scale, G if len(G) else None, h if len(h) else None,
                             A if len(A) else None, b if len(b) else None)


def check_optimum(robot, case, q, v):
    """Property 5: ``v`` equals the independent QP's optimum, where that comparison is sound.

    H >= damping I, so the optimum is unique and a KKT residual eps moves it by at most
    ~ eps / lambda_min(H) = kappa eps / lambda_max(H). The backends run at ~1e-9..1e-12
    residual tolerances (wbc.solvers.DEFAULT_SETTINGS; quadprog / DAQP are exact active-set
    methods), so the commands agree to ~kappa * eps relative: compared when kappa <= 1e7,
    with the per-backend tolerance of ACCURACY.
    """
    try:
        H, c, G, h, A, b = independent_qp(robot, case, q)
    except NotComparable as exc:
        event(f"optimum not compared: {exc}")
        return
    eigenvalues = np.linalg.eigvalsh(H)
    kappa = eigenvalues[-1] / eigenvalues[0] if eigenvalues[0] > 0 else np.inf
    if not kappa <= 1e7:
        event("optimum not compared: cond(H) > 1e7")
        return
    # a different backend from the one under test, bounds passed natively; the next one if it fails
    oracles = [name for name in ("daqp", "quadprog", "clarabel") if name != case["solver"] and name in SOLVERS]
    problem = normalised_problem(H, c, G, h, A, b, eigenvalues[-1])
    for oracle_solver in oracles:
        solution = oracle_solve(problem, oracle_solver)
        if solution.found and solution.x is not None and np.all(np.isfinite(solution.x)):
            x = solution.x  # accepted only if it really is feasible (quadprog / DAQP were seen 1e-5 out)
            if max(np.max(G @ x - h, initial=0.0), np.max(np.abs(A @ x - b), initial=0.0)) <= 1e-9:
                break
    else:
        # the controller reports a solved QP, no oracle finds one: a failure when the
        # controller's command violates the independent rows, else the oracles' trouble
        slack = max(np.max(G @ v - h, initial=0.0), np.max(np.abs(A @ v - b), initial=0.0))
        assert slack <= 1e-6, f"status 'optimal' but v = {v} violates the independent QP's rows by {slack:.2e}"
        event("optimum not compared: no oracle solved the independent QP")
        return
    reference = solution.x
    floor, eps = ACCURACY.get(case["solver"], (1e-4, 1e-9))
    tolerance = max(floor, kappa * eps) * (1.0 + np.max(np.abs(reference)))
    error = np.max(np.abs(v - reference))
    event("optimum compared")
    if error <= tolerance:
        return
    # Where the optimum is degenerate or the cost nearly flat along some direction, an answer
    # may sit ~sqrt(gap / lambda_min) away from the minimiser and still be optimal to the
    # solver's tolerance: then the cost, not the point, is what must agree (COST_ACCURACY of
    # the cost's scale) and v must satisfy the independent rows.
    def cost(x):
        return 0.5 * x @ H @ x + c @ x

    gap = (cost(v) - cost(reference)) / (eigenvalues[-1] * (1.0 + np.max(np.abs(reference))) ** 2)
    slack = max(np.max(G @ v - h, initial=0.0), np.max(np.abs(A @ v - b), initial=0.0))
    event("optimum compared by cost")
    accuracy = COST_ACCURACY.get(case["solver"], 1e-7)
    if any(item["kind"].startswith("Manipulability") for item in case["tasks"] + case["constraints"]):
        # the oracle's manipulability rows are finite differences, accepted at 1e-6 relative
        # (_manipulability_gradient): the comparison cannot be finer (seen 1.1e-7 on the 24-DOF
        # chain, where quadprog and DAQP on wbc's QP agree to 1e-13)
        accuracy = max(accuracy, 1e-6)
    assert gap <= accuracy and slack <= 1e-6, (
        f"status 'optimal' but v differs from the independent optimum by {error:.3e} (tolerance {tolerance:.1e}, "
        f"cond(H) {kappa:.1e}), its cost by {gap:.1e} (relative), rows by {slack:.1e}\n v   = {v}\n v*  = {reference}")


def check_cascade(robot, case, q, v):
    """Property 5 for strict priorities (``case["levels"]`` = s: tasks[:s] at level 0, the rest
    at level 1), from the independent QPs of each level's tasks alone (README, *Strict
    priorities*): level 0's cost ``f0`` (its tasks and their error-scaled damping, no damping)
    has its optimum ``v0`` (found by another solver) where its tasks' cost alone equals that at
    ``v`` (the band holds the task values; with the error-scaled damping v0 is unique), and
    level 1's cost ``f1`` (its tasks + damping) is no larger at ``v`` than at ``v0`` (``v``
    minimises f1 among the points with level 0's optimal task values).
    Costs relative to ``lambda_max (1 + |v|)^2`` as in :func:`check_optimum`, class 1e-3: what it
    catches are wrong cascades (a level below overriding one above: 0.1 .. 400 found), not the last
    digits -- every backend agrees with every other one to ~1e-8 on the cases where this oracle is
    2e-5 .. 7e-5 off (level 0's optimum found by an interior-point solver is accurate in its cost,
    not in its task values; the finite-difference manipulability gradient at level 0)."""
    split = case["levels"]
    if any(spec["kind"] == "SteeringTask" for spec in case["tasks"]):
        # its row follows the preview, which for a hierarchy is the cascade without constraints
        # (tests/test_hierarchy.py checks that); independent_qp writes the flat stack's
        event("cascade not compared: SteeringTask")
        return
    try:
        # level 0 has no damping (only wbc's 1e-10 floor), but its tasks' error-scaled damping mu0;
        # T0: its tasks' cost alone, which the band holds at its optimum's value
        level0 = dict(case, tasks=case["tasks"][:split])
        H0, c0, G, h, A, b = independent_qp(robot, level0, q, damping=0.0)
        T0 = independent_qp(robot, dict(level0, lm_damping=0.0), q, damping=0.0)[0]
        H1, c1, *_ = independent_qp(robot, dict(case, tasks=case["tasks"][split:]), q)
    except NotComparable as exc:
        event(f"cascade not compared: {exc}")
        return
    v0 = None
    weights = [spec[key] for spec in case["tasks"][:split]
               for key in ("cost", "position_cost", "orientation_cost") if spec.get(key)]
    if max(weights) > 1e7 * min(weights):
        # weights spanning more than 1e7 within level 0: wbc's regularisation floor (1e-10 of the
        # largest curvature) decides what the smallest weight would (a position weighted 1e-11
        # beside an orientation weighted 1e3), and the unit band rows then hold that choice
        event("cascade not compared: level-0 weights span > 1e7")
        return
    eigenvalues = np.linalg.eigvalsh(H0)
    # scaled to a unit largest curvature: a level weighted 1e-12 has entries the backends' absolute
    # tolerances would swallow (DAQP was seen 0.3 rad/s off), one weighted 1e9 made quadprog fail
    problem = normalised_problem(H0, c0, G, h, A, b, eigenvalues[-1])
    curved = eigenvalues[eigenvalues > 1e-14 * eigenvalues[-1]]  # below: rank deficiency's rounding
    if curved.size and curved[0] < 1e-7 * eigenvalues[-1]:
        # cond > 1e7 on the directions level 0 sees (e.g. a posture weighted 1e-12, or an
        # orientation 1e-8, beside a position weighted 1): wbc's regularisation floor (1e-10 of the
        # largest curvature) decides what the tiny weight would, and Clarabel's level-1 answers
        # were seen 7e-2 off while called optimal -- not compared, as in check_optimum
        event("cascade not compared: cond(H0) > 1e7")
        return
    # exact active-set methods where H0 is definite (Clarabel was seen 2e-4 off at a degenerate
    # optimum), else the backends that take a semidefinite H; never the backend under test first
    candidates = ("daqp", "quadprog", "clarabel", "proxqp") if eigenvalues[0] > 1e-9 * eigenvalues[-1] else (
        "clarabel", "proxqp")
    for oracle in sorted((n for n in candidates if n in SOLVERS), key=lambda n: n == case["solver"]):
        try:
            solution = oracle_solve(problem, oracle)
        except qpsolvers.QPError:  # e.g. ProxQP's check that q is in the range of a singular P
            continue
        x = solution.x if solution.found else None
        if x is not None and np.all(np.isfinite(x)) and max(np.max(G @ x - h, initial=0.0),
                                                              np.max(np.abs(A @ x - b), initial=0.0)) <= 1e-7:
            v0 = x
            break
    if v0 is None:
        event("cascade not compared: no oracle solved level 0")
        return
    tolerance = 1e-3
    scale = 1.0 + max(np.max(np.abs(v)), np.max(np.abs(v0)))

    def gap(H, c):  # cost at v minus cost at v0, relative
        return ((0.5 * v @ H @ v + c @ v) - (0.5 * v0 @ H @ v0 + c @ v0)) / (max(np.linalg.eigvalsh(H)[-1], 1e-300)
                                                                            * scale ** 2)

    gap0 = gap(T0, c0)
    assert gap0 <= tolerance, (f"status 'optimal' but level 0's cost at v exceeds its optimum by {gap0:.1e} "
                               f"(relative)\n v  = {v}\n v0 = {v0}")
    if np.any(H0 != T0):  # an error-scaled damping makes v0 unique: its task values are v's
        assert gap0 >= -tolerance, (f"status 'optimal' but level 0's tasks' cost at v is below that of the "
                                    f"damped optimum by {-gap0:.1e} (relative)\n v  = {v}\n v0 = {v0}")
    # v0 competes at level 1 only if it is at least as good at level 0 (an oracle's level-0
    # optimum ~1e-9 off can be far better at level 1: a flat level 0 leaves it free)
    # Level 1 only for the exact active-set backends: on a level's thin band set Clarabel's answers
    # were seen 5e-3 .. 7e-2 off in level 1's cost while called optimal (poses weighted 100 : 1e-8 ..
    # 1e-12 at level 0), where DAQP, quadprog, ProxQP, OSQP and PIQP met this oracle (README)
    if gap0 >= -1e-12 and case["solver"] in ("daqp", "quadprog"):
        gap1 = gap(H1, c1)
        assert gap1 <= tolerance, (f"status 'optimal' but level 1's cost at v exceeds that at a level-0 optimum by "
                                   f"{gap1:.1e} (relative)\n v  = {v}\n v0 = {v0}")
    event("cascade compared")


# -------------------------------------------------------------------------------- a case
def run_case(case: dict, compare_optimum: bool = True) -> dict:
    """Build and step ``case``; assert properties 1-5 on every tick, warnings as errors.
    Returns a summary."""
    with warnings_are_errors():
        return _run_case(case, compare_optimum)


def _run_case(case: dict, compare_optimum: bool) -> dict:
    try:
        robot, controller = build(case)
    except Rejected as exc:
        return {"rejected": str(exc)}
    q = np.array(case["q"])
    statuses = []
    for tick in range(case["ticks"]):
        where = f"tick {tick} at q = {q.tolist()}"
        try:
            v = controller.step(q)
        except Exception as exc:  # property 1
            raise AssertionError(f"{where}: step raised {type(exc).__name__}: {exc}") from exc
        assert isinstance(v, np.ndarray) and v.shape == (robot.nv,), f"{where}: command {v!r}"  # property 2
        assert np.all(np.isfinite(v)), f"{where}: non-finite command {v}"
        status, success = controller.last.status, controller.last.success
        assert isinstance(status, str) and status, f"{where}: status {status!r}"  # property 4
        assert success is (status == "optimal"), f"{where}: success={success!r} with status {status!r}"
        problems = hard_limit_violations(robot, case, q, v)  # property 3
        assert not problems, f"{where}: status {status!r}, hard limits violated: {problems}; v = {v.tolist()}"
        # property 6 (README "What a tick guarantees"): soft bounds are clipped into the hard
        # ones and the hard limits hold jointly at v = 0, so without a soft *row* (the barrier)
        # the QP is feasible: "a robot started outside its position limits is driven back at
        # top speed instead of hitting an infeasible QP" -- never the zero command
        if not any(c["kind"] == "ManipulabilityBarrier" for c in case["constraints"]):
            assert not status.startswith("fallback: zero command"), (
                f"{where}: feasible QP (no soft rows) answered by {status!r}")
        if success and compare_optimum:  # property 5
            if case.get("levels") is None:
                check_optimum(robot, case, q, v)
            else:
                check_cascade(robot, case, q, v)
        statuses.append(status)
        q = robot.integrate(q, v, case["dt"])
    return {"statuses": statuses}


def _label(status: str) -> str:
    return status.split(" after ")[0] if status.startswith("fallback") else status


# --------------------------------------------------------------------------------- tests
@settings(max_examples=_examples(CI_COUNTS["main"]), **FUZZ_SETTINGS)
@given(case=cases())
def test_fuzz_every_tick(case):
    note(json.dumps(case))
    result = run_case(case)
    if "rejected" in result:
        event("rejected at construction")
    for status in result.get("statuses", []):
        event(f"{case['solver']}: {_label(status)}")


class Worker:
    """A long-lived ``python tests/test_fuzz.py --worker`` fed one case per line: a crash of
    the backend (abort) kills only the worker, which is reported and restarted."""

    process: subprocess.Popen | None = None

    def run(self, case: dict) -> dict:
        if self.process is None or self.process.poll() is not None:
            self.process = subprocess.Popen([sys.executable, __file__, "--worker"], stdin=subprocess.PIPE,
                                            stdout=subprocess.PIPE, text=True, bufsize=1)
        self.process.stdin.write(json.dumps(case) + "\n")
        self.process.stdin.flush()
        line = self.process.stdout.readline()
        if not line:
            code = self.process.wait()
            self.process = None
            raise AssertionError(f"the worker process died (exit code {code}) while running this case")
        return json.loads(line)

    def close(self):
        if self.process is not None and self.process.poll() is None:
            self.process.stdin.close()
            self.process.wait(timeout=30)


@pytest.fixture(scope="module")
def worker():
    w = Worker()
    yield w
    w.close()


@pytest.mark.skipif("highs" not in SOLVERS, reason="HiGHS not installed")
@settings(max_examples=_examples(CI_COUNTS["highs"]), **FUZZ_SETTINGS)
@given(case=cases(solvers=["highs"]))
def test_fuzz_highs_in_subprocess(worker, case):
    note(json.dumps(case))
    result = worker.run(case)
    assert "failure" not in result, result["failure"]
    for status in result.get("statuses", []):
        event(f"highs: {_label(status)}")


def compatible_robots(case: dict) -> list[str]:
    """Robots a second controller on the same task/constraint objects can use: the case's own,
    and any other one with its frames when the items need no particular base."""
    portable = {"FrameTask", "PositionTask", "PostureTask", "ManipulabilityTask", "JointPositionLimits",
                "JointVelocityLimits", "ManipulabilityBarrier"}
    items = case["tasks"] + case["constraints"]
    explicit_posture = any(item["kind"] == "PostureTask" and item["target"] is not None for item in items)
    if case["reduced"] or explicit_posture or any(item["kind"] not in portable for item in items):
        return [case["robot"]]  # (a posture target is a configuration of one model)
    frames = {item["frame"] for item in items if "frame" in item}
    return [name for name in ROBOT_NAMES if frames <= set(ROBOTS[name].frame_names)
            and not (ROBOTS[name].base.is_nonholonomic)]


@settings(max_examples=_examples(CI_COUNTS["shared"]), **FUZZ_SETTINGS)
@given(case=cases(), data=st.data())
def test_fuzz_shared_objects(case, data):
    """Three controllers built on the *same* task and constraint objects -- two of the case's
    robot, one of another robot object (possibly another model) -- command what controllers
    on fresh copies command, with the same task errors, ticks interleaved (README "Sharing")."""
    note(json.dumps(case))
    with warnings_are_errors():
        _shared_objects(case, data)


def _shared_objects(case, data):
    other = dict(case, robot=data.draw(st.sampled_from(compatible_robots(case)), label="other robot"))
    try:
        robot, fresh_a = build(case)
        _, fresh_b = build(case)
        _, fresh_c = build(other)
    except Rejected:
        return
    other_robot = wbc.load_robot(ROBOTS[other["robot"]].source)  # another robot object, whatever the model
    tasks = [make_task(spec, robot) for spec in case["tasks"]]
    constraints = [make_constraint(spec) for spec in case["constraints"]]
    robots = (robot, robot, other_robot)
    split = case.get("levels")
    stack = tasks if split is None else [tasks[:split], tasks[split:]]
    shared = [wbc.Controller(r, stack, constraints, solver=case["solver"], dt=case["dt"], reduced=case["reduced"],
                             lm_damping=case.get("lm_damping", 1.0)) for r in robots]
    qs = [np.array(case["q"]), np.array(data.draw(configurations(robot), label="second q")),
          np.array(data.draw(configurations(other_robot), label="third q"))]
    for tick in range(case["ticks"]):
        for k, fresh in enumerate((fresh_a, fresh_b, fresh_c)):
            try:
                expected = fresh.step(qs[k])
            except Exception:  # noqa: BLE001 -- test_fuzz_every_tick reports escapes
                assume(False)
            got = shared[k].step(qs[k])
            assert shared[k].last.status == fresh.last.status, (
                f"tick {tick}, controller {k} ({robots[k].name}): status {shared[k].last.status!r} with shared "
                f"objects, {fresh.last.status!r} with fresh copies")
            np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9,
                                       err_msg=f"tick {tick}, controller {k} ({robots[k].name}): shared objects "
                                               "change the command")
            qs[k] = robots[k].integrate(qs[k], expected, case["dt"])
        for controller, fresh in zip(shared, (fresh_a, fresh_b, fresh_c), strict=True):
            own, alone = controller.last.task_errors, fresh.last.task_errors
            assert own.keys() == alone.keys()
            np.testing.assert_allclose([own[key] for key in own], [alone[key] for key in own], rtol=1e-9, atol=1e-12)


# ------------------------------------------------------------ the checks checked by hand
def test_hard_limit_check_on_hand_made_commands():
    """The independent hard-limit check against the README's definitions."""
    youbot, deluca, puma = ROBOTS["youbot"], ROBOTS["deluca_mm"], ROBOTS["puma560"]
    speed = dict(constraints=[dict(kind="JointVelocityLimits")])
    wheels = dict(constraints=[dict(kind="MecanumWheelLimits")])
    q = np.zeros(8)
    # arm joint exactly at its limit passes, beyond fails
    v = np.zeros(8)
    v[4] = np.pi / 2
    assert not hard_limit_violations(youbot, speed, q, v)
    v[4] = np.pi / 2 + 1e-5
    assert hard_limit_violations(youbot, speed, q, v)
    # base limits are base-frame: heading pi/4, world (0.7, 0.7) is base v_x = 0.99 > 0.8 although
    # each world component is below 0.8; world (0.5657, -0.5657) is base (0, -0.8): on the limit
    q[2] = np.pi / 4
    assert hard_limit_violations(youbot, speed, q, np.array([0.7, 0.7, 0, 0, 0, 0, 0, 0.0]))
    assert not hard_limit_violations(youbot, speed, q, np.array([0.8 * math.sqrt(0.5), -0.8 * math.sqrt(0.5),
                                                                 0, 0, 0, 0, 0, 0.0]))
    assert hard_limit_violations(youbot, speed, q, np.array([0, 0, 1.0 + 1e-5, 0, 0, 0, 0, 0.0]))
    # no speed-limit check without JointVelocityLimits (no hard speed limit in the QP then)
    assert not hard_limit_violations(youbot, dict(constraints=[]), q, np.array([5.0, 0, 0, 5, 0, 0, 0, 0]))
    # wheels: forward 0.8 m/s in the base frame = every wheel at 0.8 / r = max_speed
    forward = np.array([0.8 * math.cos(np.pi / 4), 0.8 * math.sin(np.pi / 4), 0, 0, 0, 0, 0, 0.0])
    assert not hard_limit_violations(youbot, wheels, q, forward)
    assert hard_limit_violations(youbot, wheels, q, forward * 1.001)
    # yaw alone: |u_i| = (l + w) / r |omega|; 1 rad/s -> 8.1 rad/s (fine), 2.1 rad/s -> 17.0 (beyond)
    assert not hard_limit_violations(youbot, wheels, q, np.array([0, 0, 1.0, 0, 0, 0, 0, 0.0]))
    assert hard_limit_violations(youbot, wheels, q, np.array([0, 0, 2.1, 0, 0, 0, 0, 0.0]))
    # nonholonomic: slip = -sin(th) xdot + cos(th) ydot, checked with or without constraints listed
    qd = np.zeros(6)
    qd[2] = 0.3
    along = np.array([0.4 * math.cos(0.3), 0.4 * math.sin(0.3), 0, 0, 0, 0])
    assert not hard_limit_violations(deluca, speed, qd, along)
    assert hard_limit_violations(deluca, dict(constraints=[]), qd, np.array([0, 0.01, 0, 0, 0, 0]))
    assert hard_limit_violations(deluca, speed, qd, along * 1.3)  # |v| = 0.52 > 0.5
    # fixed base: every coordinate against velocity_limit
    assert not hard_limit_violations(puma, speed, np.zeros(6), np.ones(6))
    assert hard_limit_violations(puma, speed, np.zeros(6), np.r_[np.ones(5), 1.01])


def test_independent_qp_matches_a_plain_tick():
    """The oracle agrees with the controller on an ordinary well-conditioned stack (so a
    disagreement found by the fuzzer is the library's, not the oracle's)."""
    robot = ROBOTS["youbot"]
    q = np.array([0.3, -0.2, 0.7, 0.1, 0.5, 1.0, 1.2, 0.3])
    pose = robot.frame_pose(q, "ee").copy()
    pose[:3, 3] += [0.2, -0.1, 0.05]
    pose[:3, :3] = pin.exp3(np.array([0.1, 0.2, -0.3])) @ pose[:3, :3]
    case = dict(robot="youbot", q=q.tolist(), solver="daqp", dt=0.01, reduced=False, ticks=3,
                tasks=[dict(kind="FrameTask", frame="ee", position_cost=1.0, orientation_cost=0.5, gain=0.5,
                            max_speed=0.3, max_angular_speed=None, target=pose.tolist()),
                       dict(kind="PostureTask", cost=1e-2, gain=0.1, target=None),
                       dict(kind="BaseVelocityTask", cost=0.1, target=[0.2, 0.1, 0.0]),
                       dict(kind="ManipulabilityTask", frame="ee", cost=1e-3, gain=0.1, target=0.1, rows="position")],
                constraints=[dict(kind="JointPositionLimits", gain=0.5), dict(kind="JointVelocityLimits"),
                             dict(kind="MecanumWheelLimits"),
                             dict(kind="ManipulabilityBarrier", frame="ee", min_value=1e-4, gain=0.5, rows="all")])
    result = run_case(case)
    assert result["statuses"] == ["optimal"] * 3
    deluca = ROBOTS["deluca_mm"]
    qd = np.array([0.0, 0.0, 0.4, 0.2, 0.8, 1.0])
    case = dict(robot="deluca_mm", q=qd.tolist(), solver="daqp", dt=0.01, reduced=True, ticks=3,
                tasks=[dict(kind="PositionTask", frame="wrist_center", cost=1.0, gain=0.3, max_speed=None,
                            target=(deluca.frame_pose(qd, "wrist_center")[:3, 3] + [0.3, 1.0, 0.0]).tolist()),
                       dict(kind="SteeringTask", cost=1.0, gain=0.1, speed_scale=0.1),
                       dict(kind="PostureTask", cost=1e-3, gain=1.0, target=None)],
                constraints=[dict(kind="JointPositionLimits", gain=0.5), dict(kind="JointVelocityLimits")])
    assert run_case(case)["statuses"] == ["optimal"] * 3


#: the open case of a campaign (seed 31): DAQP on two levels of a youBot, level 0 a posture weighted
#: 1e8 and a base twist weighted 1.8e9, level 1 a posture weighted 1e12; an arm joint outside its
#: limits (lb = ub there) and the base at its speed limits
SEED_31 = {"robot": "youbot", "q": [-2.933879309149294, 1.5292403500237404, 3.2805382512122367, -2.949606435870417,
                                    1.5707963267948966, -2.7459708074452873, 1.7889624832941877, -1.6224453281544011],
           "tasks": [{"kind": "PostureTask", "cost": 100000000.0, "gain": 2.1478496719271822e-07,
                      "target": [5.795917992758592e-215, 0.7014531814045357, 1.2894075404445962e-213,
                                 -1.585570473314475, -1.1344640137963142, 2.548180707911721, -1.7889624832941877,
                                 -3.1565854988582625]},
                     {"kind": "BaseVelocityTask", "cost": 1758961944.9220517,
                      "target": [-8.621948548734313e-273, -2.3239293927559137, 2.421991046261902]},
                     {"kind": "PostureTask", "cost": 1000000000000.0, "gain": 1.0,
                      "target": [-4.633341925872133e-13, -1.5733166025994323, -2.542340300256818, 2.989719539914482,
                                 -1.1344640137963142, -2.6354471705114375, 1.7889624832943418, -2.923426497090502]},
                     {"kind": "ManipulabilityTask", "frame": "ee", "cost": 1.0, "gain": 0.001,
                      "target": 4.773847480190895e-06, "rows": "all"}],
           "levels": 2, "constraints": [{"kind": "JointVelocityLimits"},
                                        {"kind": "JointPositionLimits", "gain": 0.02000103135306569},
                                        {"kind": "MecanumWheelLimits"}],
           "solver": "daqp", "dt": 0.001, "reduced": False, "ticks": 4}


def test_seed_31_is_compared_with_an_exact_level_0_optimum(monkeypatch):
    """The oracle was wrong here, not wbc: unscaled (H's largest curvature 1.8e9) quadprog called
    level 0 "inconsistent" and the oracle took Clarabel's level-0 optimum, 1.5e-4 rad/s off on the
    arm joints (its cost 3.8 higher: 3e-10 relative, within Clarabel's tolerance), which level 1's
    1e12 posture turned into a cost 0.17 relative "better" than wbc's. wbc's level-0 answer meets
    DAQP's and quadprog's on the normalised QP to 1.4e-12 rad/s. Every tick is now compared."""
    events = []
    monkeypatch.setattr(sys.modules[__name__], "event", events.append)
    assert run_case(SEED_31)["statuses"] == ["optimal"] * 4
    assert events.count("cascade compared") == 4, events


# --------------------------------------------------------------------------------- worker
def _worker_main() -> None:
    for line in sys.stdin:
        case = json.loads(line)
        try:
            result = run_case(case)
        except AssertionError as exc:
            result = {"failure": f"{exc}\n{traceback.format_exc(limit=3)}"}
        except Exception as exc:  # noqa: BLE001 -- reported to the parent as a failure
            result = {"failure": f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"}
        sys.stdout.write(json.dumps(result) + "\n")
        sys.stdout.flush()


if __name__ == "__main__" and "--worker" in sys.argv:
    _worker_main()
