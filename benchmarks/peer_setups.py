"""The same youBot task stack set up in wbc, Pink, mink, placo and by hand, for :mod:`benchmarks.peers`.

Every setup exposes ``name``, ``set_target(pose)`` (4x4 world pose of the tool),
``step(q) -> v`` and ``integrate(q, v)`` (the configuration after one tick at ``v``, the
library's own way). They are built from one :class:`StackSpec` so that gains, costs, dt,
damping, limits and solver (DAQP) are the same. Convention mapping (derived from the
peers' source, see benchmarks/README.md):

* **costs** — wbc weighs a task by ``W = diag(sqrt(cost))`` (``cost`` in [cost]/[unit]^2);
  Pink and mink multiply the residual by ``cost`` itself, so they get ``sqrt(cost)``;
* **units** — Pink and mink solve for the displacement ``dq = v dt``; their objective is
  wbc's multiplied by dt^2, so the same ``damping`` number gives the same minimiser;
* **limits** — position limits as a damper ``gain (limit - q)`` per tick in all three;
  velocity limits as a box ``|v_i| <= v_max,i`` in **world axes** for the base
  (:class:`WorldVelocityLimits` in wbc; Pink and mink cannot express wbc's base-frame
  rows). The youBot's mecanum wheel limits are not part of the peer stack;
* **pose error** — wbc: ``(p* - p, log3(R* R^T))`` world-aligned with the plain
  Jacobian; Pink and mink: the body twist ``log6(T_b^-1 T*)`` with the Jacobian
  ``Jlog6 J_body``. These are different tasks away from zero error (the position part of
  log6 follows a screw, not a straight line). :class:`Log6FrameTask` is a wbc task with
  the peers' convention: with it wbc solves exactly the peers' QP;
* **placo** (:mod:`benchmarks.placo_peer`) — wbc's pose error and Jacobian, weights =
  wbc's costs, regularisation task = ``damping``, but no gains: every task and the
  position limits remove their whole error in one tick (gain 1). :func:`placo_gains`
  is the spec with those gains: wbc on it solves placo's QP.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import wbc
from wbc.app.scenario import Scenario
from wbc.constraints.constraint import Constraint, ConstraintData, ConstraintRows
from wbc.model.kinematics import Kinematics
from wbc.model.robot import Robot
from wbc.tasks import FrameTask, PostureTask
from wbc.tasks.frame_task import FrameTaskData

from .common import MODELS
from .placo_peer import PlacoStack

URDF = MODELS / "youbot" / "youbot.urdf"
MJCF = MODELS / "youbot" / "youbot.xml"
_LOCAL = pin.ReferenceFrame.LOCAL
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass
class StackSpec:
    """FrameTask + PostureTask + position limits + velocity limits, one solver."""

    frame: str
    position_cost: float
    orientation_cost: float
    gain: float
    posture_cost: float
    posture_gain: float
    posture_target: np.ndarray
    limit_gain: float
    damping: float
    dt: float
    velocity_limit: np.ndarray  #: (nv,) world-axis box, base included
    joint_names: list[str]
    base_indices: tuple[int, ...]
    mjcf_site: str = "ee"


def spec_from_scenario(scenario: Scenario) -> StackSpec:
    """Read the frame task, posture task and position-limit gain of a youBot scenario."""
    frame = next(t for t in scenario.tasks if isinstance(t, FrameTask))
    posture = next(t for t in scenario.tasks if isinstance(t, PostureTask))
    limits = next(c for c in scenario.constraints if isinstance(c, wbc.JointPositionLimits))
    for name, values in (("position_cost", frame.position_cost), ("orientation_cost", frame.orientation_cost)):
        if np.ptp(values) != 0:
            raise ValueError(f"peer stack needs an isotropic {name}")
    posture_cost = np.atleast_1d(posture._cost_spec)
    if np.ptp(posture_cost) != 0:
        raise ValueError("peer stack needs a scalar posture cost")
    robot = scenario.robot
    target = robot.check_configuration(posture._target_spec if posture._target_spec is not None else robot.neutral())
    return StackSpec(
        frame=frame.frame, position_cost=float(frame.position_cost[0]),
        orientation_cost=float(frame.orientation_cost[0]), gain=frame.gain,
        posture_cost=float(posture_cost[0]), posture_gain=posture.gain, posture_target=target,
        limit_gain=limits.gain, damping=scenario.damping, dt=scenario.dt,
        velocity_limit=robot.velocity_limit.copy(), joint_names=list(robot.joint_names),
        base_indices=tuple(robot.base.indices) if robot.base.is_mobile else (),
    )


# ------------------------------------------------------------------ wbc pieces
class WorldVelocityLimits(Constraint, ConstraintData):
    """``|v_i| <= velocity_limit_i`` as plain bounds, base linear rates in **world** axes.

    The box Pink's and mink's ``VelocityLimit`` express; wbc's own
    :class:`~wbc.JointVelocityLimits` bounds the base speed in the base frame instead.
    """

    has_bounds = True

    def bind(self, robot: Robot) -> WorldVelocityLimits:
        self._limit = robot.velocity_limit.copy()
        return super().bind(robot)  # its own data: serves one robot object

    def write_static(self, rows: ConstraintRows) -> None:
        np.negative(self._limit, out=rows.lower)
        rows.upper[...] = self._limit

    def add_ops(self, program, kin: Kinematics, rows: ConstraintRows) -> bool:
        return True  # nothing to do per tick: the bounds are static

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        pass


class Log6FrameTask(FrameTask):
    """A wbc FrameTask with Pink's and mink's error convention (for the agreement check).

    Error: the body twist ``e = log6(T_b^-1 T*)``; rows ``W (Jlog6(T*^-1 T_b) J_body v - gain/dt e)``.
    The data's ``error`` keeps wbc's world-aligned error for reporting. Costs must be isotropic
    (wbc's weights are applied in the body frame here).
    """

    def bind(self, robot: Robot) -> Log6FrameTaskData:
        return Log6FrameTaskData(self, robot)


class Log6FrameTaskData(FrameTaskData):
    """Rows of :class:`Log6FrameTask` (in Python: no compiled op, ``compute`` overrides the parent's)."""

    def __init__(self, task: Log6FrameTask, robot: Robot) -> None:
        super().__init__(task, robot)
        self._frame_id = robot.frame_id(task.frame)

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        task = self.task
        placement = kin.frame_placement(self._frame_id)
        goal = pin.SE3(task._target_rotation, task._target_position)
        body_to_target = placement.actInv(goal)
        twist = pin.log6(body_to_target).vector
        local = pin.getFrameJacobian(kin.model, kin.data, self._frame_id, _LOCAL)
        np.matmul(pin.Jlog6(body_to_target.inverse()), local, out=jacobian)
        jacobian *= task._weights[:, None]
        np.multiply(twist, task.gain / dt, out=target)
        target *= task._weights
        self.error[:3] = task._target_position - placement.translation
        self.error[3:] = pin.log3(task._target_rotation @ placement.rotation.T)


class WbcSetup:
    """wbc's Controller on the peer stack (or any explicit list of tasks/constraints)."""

    def __init__(self, spec: StackSpec, name: str = "wbc", frame_task: type[FrameTask] = FrameTask,
                 controller: wbc.Controller | None = None) -> None:
        self.name = name
        if controller is None:
            robot = wbc.load_robot(URDF)
            self.task = frame_task(spec.frame, spec.position_cost, spec.orientation_cost, gain=spec.gain)
            posture = PostureTask(spec.posture_cost, target=spec.posture_target, gain=spec.posture_gain)
            # lm_damping 0: the peers' QP has no error-scaled damping (mink's lm_damping defaults to 0)
            controller = wbc.Controller(robot, [self.task, posture],
                                        [wbc.JointPositionLimits(gain=spec.limit_gain), WorldVelocityLimits()],
                                        solver="daqp", dt=spec.dt, damping=spec.damping, lm_damping=0.0)
        else:
            self.task = next(t for t in controller.tasks if isinstance(t, FrameTask))
        self.controller = controller

    def set_target(self, pose: np.ndarray) -> None:
        self.task.set_target(pose)

    def step(self, q: np.ndarray) -> np.ndarray:
        return self.controller.step(q)

    def integrate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self.controller.robot.integrate(q, v, self.controller.dt)


class HandRolledSetup:
    """The same QP written directly against Pinocchio and DAQP: a lower bound for a Python tick.

    No validation, no diagnostics, no generality: one frame task, the posture rows as a
    diagonal, bounds only (position damper intersected with the speed box).
    """

    def __init__(self, spec: StackSpec, name: str = "hand-rolled pinocchio + daqp") -> None:
        import daqp

        self.name = name
        self._solve = daqp.solve
        self.model = pin.buildModelFromUrdf(str(URDF))
        self.data = self.model.createData()
        self.frame_id = self.model.getFrameId(spec.frame)
        nv = self.model.nv
        self.dt, self.gain, self.posture_gain = spec.dt, spec.gain, spec.posture_gain
        self.w2 = np.array([spec.position_cost] * 3 + [spec.orientation_cost] * 3)
        arm = np.ones(nv, dtype=bool)
        arm[list(spec.base_indices)] = False
        self.posture_w2 = np.where(arm, spec.posture_cost, 0.0)
        self.posture_target = spec.posture_target.copy()
        self.H_static = np.diag(self.posture_w2 + spec.damping)
        lower, upper = self.model.lowerPositionLimit.copy(), self.model.upperPositionLimit.copy()
        lower[~arm], upper[~arm] = -np.inf, np.inf
        self.lower, self.upper, self.limit_gain = lower, upper, spec.limit_gain
        self.vmax = spec.velocity_limit.copy()
        self.A = np.zeros((0, nv))
        self.sense = np.zeros(nv, dtype=np.int32)
        self.target_R, self.target_p = np.eye(3), np.zeros(3)
        self.error = np.zeros(6)

    def set_target(self, pose: np.ndarray) -> None:
        self.target_R, self.target_p = pose[:3, :3].copy(), pose[:3, 3].copy()

    def step(self, q: np.ndarray) -> np.ndarray:
        model, data = self.model, self.data
        pin.computeJointJacobians(model, data, q)
        placement = pin.updateFramePlacement(model, data, self.frame_id)
        J = pin.getFrameJacobian(model, data, self.frame_id, _LWA)
        e = self.error
        e[:3] = self.target_p - placement.translation
        e[3:] = pin.log3(self.target_R @ placement.rotation.T)
        WJ = J * self.w2[:, None]
        H = J.T @ WJ + self.H_static
        c = -(WJ.T @ e) * (self.gain / self.dt) - self.posture_w2 * (self.posture_target - q) * (
            self.posture_gain / self.dt)
        scale = self.limit_gain / self.dt
        ub = np.minimum(self.vmax, (self.upper - q) * scale)
        lb = np.maximum(-self.vmax, (self.lower - q) * scale)
        x, _, exitflag, _ = self._solve(H, c, self.A, ub, lb, self.sense)
        if exitflag < 1:
            raise RuntimeError(f"daqp exitflag {exitflag}")
        return x

    def integrate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return pin.integrate(self.model, q, v * self.dt)


# ------------------------------------------------------------------------ peers
class PinkSetup:
    """Pink (pin-pink) on ``models/youbot/youbot.urdf``, DAQP through qpsolvers."""

    def __init__(self, spec: StackSpec, name: str = "Pink", urdf: Path = URDF) -> None:
        import pink
        from pink.limits import ConfigurationLimit, VelocityLimit
        from pink.tasks import FrameTask as PinkFrameTask
        from pink.tasks import PostureTask as PinkPostureTask

        self.name = name
        self._solve_ik = pink.solve_ik
        model = pin.buildModelFromUrdf(str(urdf))
        self.configuration = pink.Configuration(model, model.createData(), spec.posture_target.copy())
        self.task = PinkFrameTask(spec.frame, position_cost=float(np.sqrt(spec.position_cost)),
                                  orientation_cost=float(np.sqrt(spec.orientation_cost)), lm_damping=0.0,
                                  gain=spec.gain)
        posture_cost = np.full(model.nv, np.sqrt(spec.posture_cost))
        posture_cost[list(spec.base_indices)] = 0.0  # wbc's PostureTask leaves the base free
        posture = PinkPostureTask(cost=posture_cost, gain=spec.posture_gain, lm_damping=0.0)
        posture.set_target(spec.posture_target)
        self.tasks = [self.task, posture]
        # URDF base limits are placeholders (+-1000): inactive rows here, absent in wbc
        self.limits = [ConfigurationLimit(model, config_limit_gain=spec.limit_gain),
                       VelocityLimit(model, spec.velocity_limit)]
        self.dt, self.damping = spec.dt, spec.damping

    def set_target(self, pose: np.ndarray) -> None:
        self.task.set_target(pin.SE3(pose[:3, :3].copy(), pose[:3, 3].copy()))

    def step(self, q: np.ndarray) -> np.ndarray:
        self.configuration.update(q)
        return self._solve_ik(self.configuration, self.tasks, self.dt, solver="daqp", damping=self.damping,
                              limits=self.limits, safety_break=False)

    def integrate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self.configuration.integrate(v, self.dt)


class MinkSetup:
    """mink on ``models/youbot/youbot.xml`` (site ``ee``), DAQP through qpsolvers."""

    def __init__(self, spec: StackSpec, name: str = "mink", mjcf: Path = MJCF, model: Any = None) -> None:
        """``model``: an ``mujoco.MjModel`` to use instead of loading ``mjcf`` (e.g. with obstacles added)."""
        import mink
        import mujoco

        self.name = name
        self._mink = mink
        self.model = model = mujoco.MjModel.from_xml_path(str(mjcf)) if model is None else model
        names = [model.joint(i).name for i in range(model.njnt)]
        if names != spec.joint_names:
            raise ValueError(f"MJCF joints {names} differ from the URDF's {spec.joint_names}")
        self.configuration = mink.Configuration(model)
        self.task = mink.FrameTask(spec.mjcf_site, "site", position_cost=float(np.sqrt(spec.position_cost)),
                                   orientation_cost=float(np.sqrt(spec.orientation_cost)), gain=spec.gain,
                                   lm_damping=0.0)
        posture_cost = np.full(model.nv, np.sqrt(spec.posture_cost))
        posture_cost[list(spec.base_indices)] = 0.0
        posture = mink.PostureTask(model, cost=posture_cost, gain=spec.posture_gain)
        posture.set_target(spec.posture_target)
        self.tasks = [self.task, posture]
        self.limits = [mink.ConfigurationLimit(model, gain=spec.limit_gain),
                       mink.VelocityLimit(model, dict(zip(names, spec.velocity_limit, strict=True)))]
        self.dt, self.damping = spec.dt, spec.damping

    def set_target(self, pose: np.ndarray) -> None:
        self.task.set_target(self._mink.SE3.from_matrix(pose))

    def step(self, q: np.ndarray) -> np.ndarray:
        self.configuration.update(q)
        return self._mink.solve_ik(self.configuration, self.tasks, self.dt, "daqp", damping=self.damping,
                                   limits=self.limits)

    def integrate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self.configuration.integrate(v, self.dt)


def placo_gains(spec: StackSpec) -> StackSpec:
    """``spec`` with placo's fixed gains: frame task, posture task and position limits at 1."""
    return replace(spec, gain=1.0, posture_gain=1.0, limit_gain=1.0)


def placo_stack(spec: StackSpec, urdf: Path = URDF) -> dict:
    """The JSON description of the stack that :class:`~benchmarks.placo_peer.PlacoStack` builds.

    Weights are wbc's costs (placo minimises ``weight |A dq - e|^2``, wbc ``cost |J v - gain e/dt|^2``:
    the same up to dt^2); the regularisation task's magnitude is ``damping``; the posture covers
    the arm joints only (wbc's PostureTask leaves the base free). Gains are not expressible.
    """
    base = set(spec.base_indices)
    return {"urdf": str(urdf), "frame": spec.frame, "position_weight": spec.position_cost,
            "orientation_weight": spec.orientation_cost, "posture_weight": spec.posture_cost,
            "posture_target": {name: float(spec.posture_target[i]) for i, name in enumerate(spec.joint_names)
                               if i not in base},
            "regularization": spec.damping, "dt": spec.dt,
            "velocity_limits": dict(zip(spec.joint_names, map(float, spec.velocity_limit), strict=True)),
            "joint_names": list(spec.joint_names)}


class PlacoSetup(PlacoStack):
    """placo in this process (when ``import placo`` works next to wbc's Pinocchio)."""

    def __init__(self, spec: StackSpec, name: str = "placo", urdf: Path = URDF) -> None:
        super().__init__(placo_stack(spec, urdf), name)
