"""Closed-loop kinematic simulation of a scenario: ``q+ = integrate(q, v, dt)`` each tick."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .constraints import ManipulabilityBarrier
from .controller import Controller
from .manipulability import manipulability
from .scenario import Scenario
from .tasks import FrameTask, ManipulabilityTask, PostureTask


@dataclass
class RunResult:
    """Time series of one closed-loop run (one row per tick)."""

    scenario: str
    solver: str
    dt: float
    time: np.ndarray  #: (T,) [s]
    q: np.ndarray  #: (T+1, nq) configurations, q[0] = initial
    v: np.ndarray  #: (T, nv) commands
    position_error: np.ndarray  #: (T,) [m] of the reference task, before each command
    orientation_error: np.ndarray  #: (T,) [rad]
    solve_time: np.ndarray  #: (T,) [s]
    tick_time: np.ndarray  #: (T,) [s], whole Controller.step
    position_violation: np.ndarray  #: (T+1,) max over joints of distance outside [lower, upper]
    velocity_violation: np.ndarray  #: (T,) max over coordinates of |v| beyond its limit
    velocity_ratio: np.ndarray  #: (T, nv) |v_i| / limit_i (base linear entries in the base frame)
    fallback_ticks: int = 0  #: ticks whose command came from a fallback (last.success False)
    base_path: np.ndarray | None = None  #: (T+1, 2) base (x, y) [m] of a mobile base
    tool_path: np.ndarray | None = None  #: (T+1, 3) world position [m] of the reference task's frame
    wheel_ratio: np.ndarray | None = None  #: (T, n_wheels) |u_i| / u_max, if the base has wheels
    lateral_slip: np.ndarray | None = None  #: (T,) |base-frame v_y| [m/s] of a nonholonomic base
    #: whether the reference task weighs the orientation (a FrameTask with an orientation cost > 0);
    #: if not, ``orientation_error`` is not a tracking error (0, or an unweighted error)
    orientation_tracked: bool = True

    def summary(self) -> dict[str, float]:
        """The numbers ``wbc run`` prints (the orientation errors only if the orientation is tracked)."""
        us = 1e6
        summary = {
            "ticks": int(self.time.size),
            "fallback_ticks": self.fallback_ticks,
            "position_error_rms_m": float(np.sqrt(np.mean(self.position_error ** 2))),
            "position_error_max_m": float(self.position_error.max()),
            "final_position_error_m": float(self.position_error[-1]),
        }
        if self.orientation_tracked:
            summary["orientation_error_rms_rad"] = float(np.sqrt(np.mean(self.orientation_error ** 2)))
            summary["orientation_error_max_rad"] = float(self.orientation_error.max())
            summary["final_orientation_error_rad"] = float(self.orientation_error[-1])
        summary |= {
            "worst_position_limit_violation": float(self.position_violation.max()),
            "worst_velocity_limit_violation": float(self.velocity_violation.max()),
            "tick_latency_median_us": float(np.median(self.tick_time) * us),
            "tick_latency_p99_us": float(np.percentile(self.tick_time, 99) * us),
            "solve_time_median_us": float(np.median(self.solve_time) * us),
        }
        if self.wheel_ratio is not None:
            summary["worst_wheel_speed_ratio"] = float(self.wheel_ratio.max())
        if self.lateral_slip is not None:
            summary["max_lateral_slip_m_s"] = float(self.lateral_slip.max())
        return summary


#: ``on_tick(k, q)`` of :func:`run`: called after tick ``k - 1`` with the configuration ``q[k]``
TickObserver = Callable[[int, np.ndarray], None]


def tick_count(scenario: Scenario, duration: float | None = None) -> int:
    """Ticks of a run of ``scenario``: its own, or ``duration`` [s] worth of its period."""
    return scenario.ticks if duration is None else int(round(duration / scenario.dt))


def run(scenario: Scenario, solver: str | None = None, duration: float | None = None,
        progress: bool = False, controller: Controller | None = None, simulation=None,
        on_tick: TickObserver | None = None) -> RunResult:
    """Run ``scenario`` in closed loop and record everything needed for the summary and plots.

    Without ``simulation`` the loop is kinematic, ``q <- integrate(q, v, dt)``. With a
    :class:`~wbc.simulation.MujocoSimulation` the controller sees the (noisy) measured
    positions, the servos track ``v`` in MuJoCo, and the recorded ``q`` and tracking
    errors are those of the true simulated state. ``on_tick(k, q)``, if given, sees every
    new configuration as it is reached (``k`` = 1 .. ticks; the live 3-D view streams the run
    through it); it runs outside ``Controller.step``, so it does not enter the recorded latencies,
    and it must not modify ``q``.
    """
    controller = controller or scenario.make_controller(solver)
    robot, dt = scenario.robot, scenario.dt
    ticks = tick_count(scenario, duration)
    q = scenario.q0.copy()
    if simulation is not None:
        simulation.reset(q)
    qs = np.zeros((ticks + 1, robot.nq))
    vs = np.zeros((ticks, robot.nv))
    pos_err, ori_err = np.zeros(ticks), np.zeros(ticks)
    solve_t, tick_t = np.zeros(ticks), np.zeros(ticks)
    qs[0] = q
    task, reference = scenario.reference_task, scenario.reference
    task_data = controller.data(task) if task is not None else None
    fallbacks = 0
    iterator = range(ticks)
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=scenario.name, unit="tick", mininterval=0.5, leave=False)
    for k in iterator:
        if reference is not None:
            task.set_target(*reference(k * dt))
        v = controller.step(q if simulation is None else simulation.measure())
        last = controller.last
        fallbacks += not last.success
        if task is not None:
            error = task_data.error if simulation is None else _true_error(robot, task, q, reference(k * dt)[0])
            pos_err[k] = np.linalg.norm(error[:3])
            ori_err[k] = np.linalg.norm(error[3:])  # 0 for a PositionTask
        solve_t[k], tick_t[k] = last.solve_time, last.tick_time
        vs[k] = v
        if simulation is None:
            q = robot.integrate(q, v, dt)
        else:
            simulation.apply(v)
            simulation.advance()
            q = simulation.q
        qs[k + 1] = q
        if on_tick is not None:
            on_tick(k + 1, qs[k + 1])
    ratio = velocity_ratio(robot, qs[:-1], vs)
    return RunResult(
        scenario=scenario.name, solver=controller.solver.name, dt=dt, time=np.arange(ticks) * dt,
        q=qs, v=vs, position_error=pos_err, orientation_error=ori_err, solve_time=solve_t, tick_time=tick_t,
        position_violation=position_violation(robot, qs),
        velocity_violation=np.max(np.maximum(ratio - 1.0, 0.0) * robot.velocity_limit, axis=1),
        velocity_ratio=ratio, fallback_ticks=fallbacks,
        base_path=qs[:, list(robot.base.indices[:2])] if robot.base.is_mobile else None,
        tool_path=None if task is None else np.array([robot.frame_pose(q, task.frame)[:3, 3] for q in qs]),
        wheel_ratio=wheel_ratio(robot, qs[:-1], vs),
        lateral_slip=lateral_slip(robot, qs[:-1], vs),
        orientation_tracked=orientation_tracked(task),
    )


def orientation_tracked(task) -> bool:
    """Whether a reference task weighs the orientation (a FrameTask with an orientation cost > 0)."""
    return isinstance(task, FrameTask) and bool(np.any(task.orientation_cost > 0))


@dataclass
class ManipulabilityTrace:
    """m(t) of one frame in every run of the same robot, and the floor of the barrier that defines it (if any)."""

    frame: str
    rows: str
    min_value: float | None
    #: one (T+1,) array per run, m at each recorded configuration; None for a run of another robot
    series: list[np.ndarray | None]
    guarded: list[bool]  #: per run, whether its scenario has a barrier with that floor on this frame and rows

    def summary(self, run: int) -> dict[str, float | str]:
        """The smallest m of run number ``run``, the frame and rows it refers to, and the floor
        of the barrier if that run has it (empty for a run of another robot)."""
        if self.series[run] is None:
            return {}
        floor = {"manipulability_floor": self.min_value} if self.guarded[run] else {}
        return {"manipulability_frame": self.frame, "manipulability_rows": self.rows,
                "manipulability_min": float(self.series[run].min())} | floor


def manipulability_traces(runs: Sequence[tuple[Scenario, RunResult]]) -> ManipulabilityTrace | None:
    """m(t) of every run for the frame of the first ManipulabilityBarrier (else ManipulabilityTask)
    found in the scenarios, or None if none has one. Runs of the same robot without it are
    evaluated all the same, which is what a with/without comparison needs."""
    watched = [(scenario.robot.name, item) for scenario, _ in runs for item in scenario.constraints + scenario.tasks
               if isinstance(item, (ManipulabilityBarrier, ManipulabilityTask))]
    if not watched:
        return None
    robot_name, first = next((pair for pair in watched if isinstance(pair[1], ManipulabilityBarrier)), watched[0])
    floor = first.min_value if isinstance(first, ManipulabilityBarrier) else None
    series = [np.array([manipulability(scenario.robot, q, first.frame, first.rows) for q in result.q])
              if scenario.robot.name == robot_name else None
              for scenario, result in runs]
    guarded = [floor is not None and any(isinstance(item, ManipulabilityBarrier) and item.min_value == floor
                                         and (item.frame, item.rows) == (first.frame, first.rows)
                                         for item in scenario.constraints)
               for scenario, _ in runs]
    return ManipulabilityTrace(first.frame, first.rows, floor, series, guarded)


def posture_traces(runs: Sequence[tuple[Scenario, RunResult]]) -> list[np.ndarray | None] | None:
    """When some scenario has priority levels: the error ``|q* (-) q|`` of the first PostureTask
    of every run at each recorded configuration (one (T+1,) array per run, None for a run
    without one) -- how far the posture got in the null space, next to the same stack weighted;
    None when no scenario has levels."""
    if not any(scenario.levels for scenario, _ in runs):
        return None
    series = []
    for scenario, result in runs:
        task = next((task for task in scenario.tasks if isinstance(task, PostureTask)), None)
        if task is None:
            series.append(None)
            continue
        data, model = task.bind(scenario.robot), scenario.robot.model
        series.append(np.array([np.linalg.norm(pin.difference(model, q, data.target)[data.indices])
                                for q in result.q]))
    return series


def _true_error(robot, task, q: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The reference task's error at the true configuration ``q`` (position; orientation)."""
    pose = robot.frame_pose(q, task.frame)
    if target.shape == (3,):
        return target - pose[:3, 3]
    return np.concatenate([target[:3, 3] - pose[:3, 3], pin.log3(target[:3, :3] @ pose[:3, :3].T)])


def wheel_ratio(robot, qs: np.ndarray, vs: np.ndarray) -> np.ndarray | None:
    """(T, n_wheels) ``|u_i| / u_max`` of a wheeled base with a declared speed limit, else None."""
    wheels = robot.base.wheels
    if wheels is None or not np.isfinite(wheels.max_speed):
        return None
    return np.abs(robot.base.twist(qs, vs) @ wheels.inverse_matrix().T) / wheels.max_speed


def lateral_slip(robot, qs: np.ndarray, vs: np.ndarray) -> np.ndarray | None:
    """(T,) sideways base speed [m/s] of a nonholonomic base, else None."""
    if not robot.base.is_nonholonomic:
        return None
    return np.abs(robot.base.twist(qs, vs)[:, 1])


def position_violation(robot, qs: np.ndarray) -> np.ndarray:
    """Per row of ``qs``: largest distance outside the position limits (0 inside)."""
    with np.errstate(invalid="ignore"):
        above = np.where(np.isfinite(robot.upper), qs - robot.upper, 0.0)
        below = np.where(np.isfinite(robot.lower), robot.lower - qs, 0.0)
    return np.max(np.maximum(np.maximum(above, below), 0.0), axis=1)


def velocity_ratio(robot, qs: np.ndarray, vs: np.ndarray) -> np.ndarray:
    """``|v_i| / limit_i`` per tick; mobile-base linear speeds are taken in the base frame."""
    speeds = np.abs(vs)
    if robot.base.is_mobile:
        x, y, _ = robot.base.indices
        twists = robot.base.twist(qs, vs)
        speeds[:, x], speeds[:, y] = np.abs(twists[:, 0]), np.abs(twists[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(robot.velocity_limit), speeds / robot.velocity_limit, 0.0)
