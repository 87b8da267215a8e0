"""Closed-loop kinematic simulation of a scenario: ``q+ = integrate(q, v, dt)`` each tick."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ..collision import CollisionAvoidance, Distances
from ..constraints import ManipulabilityBarrier
from ..control.controller import Controller
from ..core.errors import InvalidInputError
from ..model.manipulability import manipulability
from ..model.robot import Robot
from ..tasks import FrameTask, ManipulabilityTask, PositionTask, PostureTask, Task
from ..tasks.frame_task import FrameTaskData
from ..tasks.position_task import PositionTaskData
from .scenario import Scenario

if TYPE_CHECKING:
    from .simulation import MujocoSimulation


MAX_ROWS = 100_000  #: rows a run keeps by default: a longer run keeps every k-th tick (RunResult.stride)
CHUNK_TICKS = 4096  #: ticks buffered at full resolution before they are reduced to rows


class ConflictEpisode(NamedTuple):
    """A run of consecutive ticks answered by a fallback, with the constraints found in conflict
    at its first tick (``Controller.last.conflicts``)."""

    tick: int  #: the episode's first tick (1 = the first step)
    constraints: tuple[str, ...]  #: labels of the conflicting constraints (empty: none found)


@dataclass
class RunStatistics:
    """The summary numbers of a run, over every tick whatever the rows kept: sums of squares,
    maxima and final values accumulated chunk by chunk, latency percentiles from every tick's
    latency."""

    ticks: int
    fallback_ticks: int  #: ticks whose command came from a fallback (last.success False)
    position_error_rms: float  #: [m]
    position_error_max: float
    final_position_error: float
    orientation_error_rms: float  #: [rad]
    orientation_error_max: float
    final_orientation_error: float
    worst_position_violation: float  #: over q[0] .. q[ticks]
    worst_velocity_violation: float
    tick_latency_median: float  #: [s]
    tick_latency_p99: float
    solve_time_median: float
    worst_wheel_ratio: float | None = None
    max_lateral_slip: float | None = None  #: [m/s]


@dataclass
class RunResult:
    """Time series of one closed-loop run, one row per tick -- or, for a run longer than
    ``max_rows`` ticks (:func:`run`), one row per ``stride`` ticks: then ``q``, ``v`` and the
    paths are those of the row's first tick and every other series holds the largest value
    over the row's ticks (a peak is never lost). The summary numbers (:attr:`statistics`)
    are over every tick either way."""

    scenario: str
    solver: str
    dt: float
    time: NDArray[np.float64]  #: (R,) [s] of each row's first tick
    q: NDArray[np.float64]  #: (R+1, nq) configurations, q[0] = initial, q[R] = final
    v: NDArray[np.float64]  #: (R, nv) commands
    position_error: NDArray[np.float64]  #: (R,) [m] of the reference task, before each command
    orientation_error: NDArray[np.float64]  #: (R,) [rad]
    solve_time: NDArray[np.float64]  #: (R,) [s]
    tick_time: NDArray[np.float64]  #: (R,) [s], Controller.last.tick_time (on the one-call path: the native call)
    position_violation: NDArray[np.float64]  #: (R+1,) max over joints of distance outside [lower, upper]
    velocity_violation: NDArray[np.float64]  #: (R,) max over coordinates of ``|v|`` beyond its limit
    velocity_ratio: NDArray[np.float64]  #: (R, nv) ``|v_i| / limit_i`` (base linear entries in the base frame)
    statistics: RunStatistics  #: the summary numbers, over every tick
    fallback_ticks: int = 0  #: ticks whose command came from a fallback (last.success False)
    base_path: NDArray[np.float64] | None = None  #: (R+1, 2) base (x, y) [m] of a mobile base
    tool_path: NDArray[np.float64] | None = None  #: (R+1, 3) world position [m] of the reference task's frame
    wheel_ratio: NDArray[np.float64] | None = None  #: (R, n_wheels) ``|u_i| / u_max``, if the base has wheels
    lateral_slip: NDArray[np.float64] | None = None  #: (R,) ``|base-frame v_y|`` [m/s] of a nonholonomic base
    #: whether the reference task weighs the orientation (a FrameTask with an orientation cost > 0);
    #: if not, ``orientation_error`` is not a tracking error (0, or an unweighted error)
    orientation_tracked: bool = True
    stride: int = 1  #: ticks per row
    loop: str = "kinematic"  #: how the loop was closed: "kinematic", or "mujoco" (:attr:`loop_details`)
    loop_details: str = ""  #: e.g. "velocity servos, noise 0.0001, delay 1 tick" of a MuJoCo loop
    #: each episode of ticks answered by a fallback, with the constraints in conflict at its first tick
    conflicts: list[ConflictEpisode] = field(default_factory=list)

    @property
    def ticks(self) -> int:
        """Ticks run (``stride`` times the rows, or fewer in the last row)."""
        return self.statistics.ticks

    def coarsened(self, rows: int) -> RunResult:
        """This run with at most ``rows`` rows: each ``k = ceil(R / rows)`` rows merged into one
        as :func:`run` merges ticks (the first row's q, v and paths, the peak of every other
        series; ``stride`` multiplied by k). ``self`` if it has no more than ``rows`` rows.

        Raises:
            InvalidInputError: ``rows`` is not an int >= 1.
        """
        if isinstance(rows, bool) or not isinstance(rows, int) or rows < 1:
            raise InvalidInputError(f"rows must be an int >= 1, got {rows!r}")
        count = self.time.size
        k = -(-count // rows)
        if k <= 1:
            return self
        starts = np.arange(0, count, k)
        kept = np.append(starts, count)  # and the final configuration

        def peaks(series: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.maximum.reduceat(series, starts, axis=0)

        return replace(
            self, time=self.time[starts], q=self.q[kept], v=self.v[starts],
            position_error=peaks(self.position_error), orientation_error=peaks(self.orientation_error),
            solve_time=peaks(self.solve_time), tick_time=peaks(self.tick_time),
            position_violation=np.concatenate([self.position_violation[:1], peaks(self.position_violation[1:])]),
            velocity_violation=peaks(self.velocity_violation), velocity_ratio=peaks(self.velocity_ratio),
            base_path=None if self.base_path is None else self.base_path[kept],
            tool_path=None if self.tool_path is None else self.tool_path[kept],
            wheel_ratio=None if self.wheel_ratio is None else peaks(self.wheel_ratio),
            lateral_slip=None if self.lateral_slip is None else peaks(self.lateral_slip), stride=self.stride * k)

    def summary(self) -> dict[str, float]:
        """The numbers ``wbc run`` prints (the orientation errors only if the orientation is
        tracked), over every tick of the run."""
        us, s = 1e6, self.statistics
        summary: dict[str, float] = {
            "ticks": s.ticks,
            "fallback_ticks": s.fallback_ticks,
            "position_error_rms_m": s.position_error_rms,
            "position_error_max_m": s.position_error_max,
            "final_position_error_m": s.final_position_error,
        }
        if self.orientation_tracked:
            summary["orientation_error_rms_rad"] = s.orientation_error_rms
            summary["orientation_error_max_rad"] = s.orientation_error_max
            summary["final_orientation_error_rad"] = s.final_orientation_error
        summary |= {
            "worst_position_limit_violation": s.worst_position_violation,
            "worst_velocity_limit_violation": s.worst_velocity_violation,
            "tick_latency_median_us": s.tick_latency_median * us,
            "tick_latency_p99_us": s.tick_latency_p99 * us,
            "solve_time_median_us": s.solve_time_median * us,
        }
        if s.worst_wheel_ratio is not None:
            summary["worst_wheel_speed_ratio"] = s.worst_wheel_ratio
        if s.max_lateral_slip is not None:
            summary["max_lateral_slip_m_s"] = s.max_lateral_slip
        return summary


#: ``on_tick(k, q)`` of :func:`run`: called after tick ``k - 1`` with the configuration ``q[k]``
TickObserver = Callable[[int, NDArray[np.float64]], None]


def tick_count(scenario: Scenario, duration: float | None = None) -> int:
    """Ticks of a run of ``scenario``: its own, or ``duration`` [s] worth of its period."""
    return scenario.ticks if duration is None else int(round(duration / scenario.dt))


def run(scenario: Scenario, solver: str | None = None, duration: float | None = None,
        progress: bool = False, controller: Controller | None = None, simulation: MujocoSimulation | None = None,
        on_tick: TickObserver | None = None, max_rows: int | None = MAX_ROWS) -> RunResult:
    """Run ``scenario`` in closed loop and record everything needed for the summary and plots.

    Without ``simulation`` the loop is kinematic, ``q <- integrate(q, v, dt)``. With a
    :class:`~wbc.app.simulation.MujocoSimulation` the controller sees the (noisy) measured
    positions, the servos track ``v`` in MuJoCo, and the recorded ``q`` and tracking
    errors are those of the true simulated state. ``on_tick(k, q)``, if given, sees every
    new configuration as it is reached (``k`` = 1 .. ticks; the live 3-D view streams the run
    through it); it runs outside ``Controller.step``, so it does not enter the recorded latencies,
    and it must not modify ``q``.

    Memory is bounded: a run of more than ``max_rows`` ticks keeps one row per
    ``stride = ceil(ticks / max_rows)`` ticks (see :class:`RunResult`; ``None``: every tick),
    plus 16 bytes per tick for the exact latency percentiles of the summary.

    Args:
        scenario: what to run, from ``scenario.q0``; each tick ``scenario.reference`` (if any)
            sets the target of ``scenario.reference_task``, whose errors are recorded.
        solver: the QP solver (:func:`wbc.solvers.available_solvers`); None: the scenario's.
        duration: [s] instead of the scenario's duration (rounded to whole ticks).
        progress: show a progress bar on stderr.
        controller: the controller to run (built from ``scenario``) instead of
            ``scenario.make_controller(solver)``; ``solver`` is then not used.
        simulation: close the loop through this MuJoCo simulation (reset to ``scenario.q0``).
        on_tick: the observer described above.
        max_rows: rows kept at most (an int >= 1), or None for one row per tick.

    Returns:
        The time series of the run (one row per ``stride`` ticks) and its summary numbers over
        every tick (:attr:`RunResult.statistics`).

    Raises:
        InvalidInputError: ``duration`` is less than half a tick, ``max_rows`` is not an
            int >= 1 or None, or ``scenario.reference`` is set without a ``reference_task`` to
            move; or what :meth:`wbc.control.controller.Controller.step` raises (e.g. a task without a
            target).
    """
    controller = controller or scenario.make_controller(solver)
    robot, dt = scenario.robot, scenario.dt
    ticks = tick_count(scenario, duration)
    if ticks < 1:
        raise InvalidInputError(f"a run needs at least one tick: {duration} s is less than half of dt = {dt} s")
    if max_rows is not None and (isinstance(max_rows, bool) or not isinstance(max_rows, int) or max_rows < 1):
        raise InvalidInputError(f"max_rows must be an int >= 1 or None, got {max_rows!r}")
    task, reference = scenario.reference_task, scenario.reference
    if reference is not None and task is None:
        raise InvalidInputError(f"scenario {scenario.name!r} has a reference but no reference_task: set "
                                "reference_task to the FrameTask or PositionTask whose target the reference moves")
    q = scenario.q0.copy()
    if simulation is not None:
        simulation.reset(q)
    record = _Recorder(robot, None if task is None else task.frame, q, ticks, max_rows or ticks)
    task_data = None if task is None else _reference_data(controller, task)
    iterator: Iterable[int] = range(ticks)
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=scenario.name, unit="tick", mininterval=0.5, leave=False)
    for k in iterator:
        if reference is not None:
            assert task is not None  # refused above
            task.set_target(*reference(k * dt))
        v = controller.step(q if simulation is None else simulation.measure())
        last = controller.last
        position_error = orientation_error = 0.0
        if task_data is not None:
            error = task_data.error if simulation is None else _true_error(robot, task_data.task, q)
            position_error = float(np.linalg.norm(error[:3]))
            orientation_error = float(np.linalg.norm(error[3:]))  # 0 for a PositionTask
        if simulation is None:
            q = robot.integrate(q, v, dt)
        else:
            simulation.apply(v)
            simulation.advance()
            q = simulation.q
        record.tick(v, q, position_error, orientation_error, last.solve_time, last.tick_time, not last.success)
        if not last.success and record.succeeded:  # the first tick of an episode
            record.conflicts.append(ConflictEpisode(k + 1, tuple(last.conflicts)))
        record.succeeded = last.success
        if on_tick is not None:
            on_tick(k + 1, q)
    return record.result(scenario.name, controller.solver.name, dt, orientation_tracked(task), simulation)


def _reference_data(controller: Controller, task: FrameTask | PositionTask) -> FrameTaskData | PositionTaskData:
    """The controller's data of the reference task: the error of its last tick."""
    data = controller.data(task)
    assert isinstance(data, (FrameTaskData, PositionTaskData))  # what FrameTask / PositionTask.bind return
    return data


class _Recorder:
    """The record of a run as it goes: each tick into a buffer of ``chunk`` ticks; each full
    buffer is reduced to rows (one per ``stride`` ticks: the first tick's q and v, the
    largest value of every other series -- so the largest over the rows is the largest
    over every tick) and its squared errors are summed for the RMS."""

    def __init__(self, robot: Robot, frame: str | None, q0: NDArray[np.float64], ticks: int, max_rows: int) -> None:
        self.robot, self.frame, self.ticks = robot, frame, ticks
        self.stride = stride = -(-ticks // max_rows)
        rows = -(-ticks // stride)
        self.chunk = chunk = stride * max(1, CHUNK_TICKS // stride)
        nq, nv = robot.nq, robot.nv
        # rows kept
        self.q, self.v = np.empty((rows + 1, nq)), np.empty((rows, nv))
        self.position_error, self.orientation_error = np.empty(rows), np.empty(rows)
        self.solve_time, self.tick_time = np.empty(rows), np.empty(rows)
        self.position_violation, self.velocity_violation = np.empty(rows + 1), np.empty(rows)
        self.velocity_ratio = np.empty((rows, nv))
        self.tool_path = None if frame is None else np.empty((rows + 1, 3))
        wheels = robot.base.wheels
        self.wheel_ratio = (np.empty((rows, wheels.inverse_matrix().shape[0]))
                            if wheels is not None and np.isfinite(wheels.max_speed) else None)
        self.lateral_slip = np.empty(rows) if robot.base.is_nonholonomic else None
        # every tick: the latencies (for exact percentiles)
        self.all_solve_times, self.all_tick_times = np.empty(ticks), np.empty(ticks)
        # the buffer: q[0] is the configuration the buffer's first tick starts from
        self._q, self._v = np.empty((chunk + 1, nq)), np.empty((chunk, nv))
        self._errors = np.empty((chunk, 2))
        self._q[0] = q0
        self.q[0], self.position_violation[0] = q0, position_violation(robot, q0[None])[0]
        if self.tool_path is not None and frame is not None:
            self.tool_path[0] = robot.frame_pose(q0, frame)[:3, 3]
        self.done = self.buffered = self.fallbacks = 0  # ticks reduced to rows, ticks in the buffer
        self.conflicts: list[ConflictEpisode] = []  # episodes of fallback ticks
        self.succeeded = True  # whether the last tick was answered by the full QP
        self.squares = np.zeros(2)  # sums of the squared position and orientation errors
        self.final_errors = np.zeros(2)

    def tick(self, v: NDArray[np.float64], q: NDArray[np.float64], position_error: float, orientation_error: float,
             solve_time: float, tick_time: float, fallback: bool) -> None:
        """One tick: command ``v`` (from the previous configuration) led to ``q``."""
        j, k = self.buffered, self.done + self.buffered
        self._v[j], self._q[j + 1] = v, q
        self._errors[j] = position_error, orientation_error
        self.all_solve_times[k], self.all_tick_times[k] = solve_time, tick_time
        self.fallbacks += fallback
        self.buffered += 1
        if self.buffered == self.chunk:
            self._reduce()

    def _reduce(self) -> None:
        """Fold the buffered ticks into the statistics and the rows (the last row may hold
        fewer than ``stride`` ticks: only at the end of the run)."""
        n, robot = self.buffered, self.robot
        if n == 0:
            return
        qs, vs, errors = self._q[:n + 1], self._v[:n], self._errors[:n]
        ratio = velocity_ratio(robot, qs[:-1], vs)
        series = {"errors": errors, "position_violation": position_violation(robot, qs[1:]),
                  "velocity_violation": np.max(np.maximum(ratio - 1.0, 0.0) * robot.velocity_limit, axis=1),
                  "velocity_ratio": ratio, "wheel_ratio": wheel_ratio(robot, qs[:-1], vs),
                  "lateral_slip": lateral_slip(robot, qs[:-1], vs),
                  "times": np.column_stack([self.all_solve_times[self.done:self.done + n],
                                            self.all_tick_times[self.done:self.done + n]])}
        self.squares += np.sum(errors ** 2, axis=0)
        self.final_errors[:] = errors[-1]
        starts = np.arange(0, n, self.stride)
        rows = slice(self.done // self.stride, self.done // self.stride + starts.size)
        peaks = {name: np.maximum.reduceat(values, starts, axis=0) for name, values in series.items()
                 if values is not None}
        self.q[rows], self.v[rows] = qs[starts], vs[starts]
        self.position_error[rows], self.orientation_error[rows] = peaks["errors"].T
        self.solve_time[rows], self.tick_time[rows] = peaks["times"].T
        self.position_violation[1:][rows] = peaks["position_violation"]
        self.velocity_violation[rows], self.velocity_ratio[rows] = peaks["velocity_violation"], peaks["velocity_ratio"]
        if self.wheel_ratio is not None:
            self.wheel_ratio[rows] = peaks["wheel_ratio"]
        if self.lateral_slip is not None:
            self.lateral_slip[rows] = peaks["lateral_slip"]
        if self.tool_path is not None and self.frame is not None:
            self.tool_path[rows] = [self.robot.frame_pose(q, self.frame)[:3, 3] for q in qs[starts]]
        self.done += n
        self._q[0] = qs[n]
        self.buffered = 0

    def result(self, scenario: str, solver: str, dt: float, tracked: bool,
               simulation: MujocoSimulation | None) -> RunResult:
        """The run's :class:`RunResult` (after its last tick)."""
        q_end = self._q[self.buffered].copy()
        self._reduce()
        self.q[-1] = q_end
        if self.tool_path is not None and self.frame is not None:
            self.tool_path[-1] = self.robot.frame_pose(q_end, self.frame)[:3, 3]
        robot = self.robot
        rms = np.sqrt(self.squares / self.ticks)
        statistics = RunStatistics(
            ticks=self.ticks, fallback_ticks=self.fallbacks,
            position_error_rms=float(rms[0]), position_error_max=float(self.position_error.max()),
            final_position_error=float(self.final_errors[0]),
            orientation_error_rms=float(rms[1]), orientation_error_max=float(self.orientation_error.max()),
            final_orientation_error=float(self.final_errors[1]),
            worst_position_violation=float(self.position_violation.max()),
            worst_velocity_violation=float(self.velocity_violation.max()),
            tick_latency_median=float(np.median(self.all_tick_times)),
            tick_latency_p99=float(np.percentile(self.all_tick_times, 99)),
            solve_time_median=float(np.median(self.all_solve_times)),
            worst_wheel_ratio=None if self.wheel_ratio is None else float(self.wheel_ratio.max()),
            max_lateral_slip=None if self.lateral_slip is None else float(self.lateral_slip.max()))
        loop, details = ("kinematic", "") if simulation is None else (
            "mujoco", f"velocity servos, noise {simulation.noise:g}, delay {simulation.delay} tick"
                      f"{'s' if simulation.delay != 1 else ''}")
        rows = self.q.shape[0] - 1
        return RunResult(
            scenario=scenario, solver=solver, dt=dt, time=np.arange(rows, dtype=np.float64) * self.stride * dt,
            q=self.q, v=self.v, position_error=self.position_error, orientation_error=self.orientation_error,
            solve_time=self.solve_time, tick_time=self.tick_time, position_violation=self.position_violation,
            velocity_violation=self.velocity_violation, velocity_ratio=self.velocity_ratio, statistics=statistics,
            fallback_ticks=self.fallbacks, base_path=self.q[:, list(robot.base.indices[:2])] if robot.base.is_mobile
            else None, tool_path=self.tool_path, wheel_ratio=self.wheel_ratio, lateral_slip=self.lateral_slip,
            orientation_tracked=tracked, stride=self.stride, loop=loop, loop_details=details, conflicts=self.conflicts)


def orientation_tracked(task: Task | None) -> bool:
    """Whether a reference task weighs the orientation (a FrameTask with an orientation cost > 0)."""
    return isinstance(task, FrameTask) and bool(np.any(task.orientation_cost > 0))


@dataclass
class ManipulabilityTrace:
    """m(t) of one frame in every run of the same robot, and the floor of the barrier that defines it (if any)."""

    frame: str
    rows: str
    min_value: float | None
    #: one (T+1,) array per run, m at each recorded configuration; None for a run of another robot
    series: list[NDArray[np.float64] | None]
    guarded: list[bool]  #: per run, whether its scenario has a barrier with that floor on this frame and rows
    #: per run, the ticks per recorded row (RunResult.stride): m is evaluated at the rows' configurations
    strides: list[int] = field(default_factory=list)

    def summary(self, run: int) -> dict[str, float | str]:
        """The smallest m of run number ``run``, the frame and rows it refers to, the floor of
        the barrier if that run has it, and for a long run whose record keeps one configuration
        per ``stride`` ticks, that stride (m is then the smallest at those ticks); empty for a
        run of another robot."""
        series = self.series[run]
        if series is None:
            return {}
        summary: dict[str, float | str] = {"manipulability_frame": self.frame, "manipulability_rows": self.rows,
                                           "manipulability_min": float(series.min())}
        if self.guarded[run] and self.min_value is not None:  # (a guarded run has a floor)
            summary["manipulability_floor"] = self.min_value
        stride = self.strides[run] if self.strides else 1
        if stride > 1:
            summary["manipulability_sampled_every_ticks"] = stride
        return summary


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
    series = [np.array([manipulability(scenario.robot, q, first.frame, first.rows, first.joints) for q in result.q])
              if scenario.robot.name == robot_name else None
              for scenario, result in runs]
    watched_measure = (first.frame, first.rows, first.joints)
    guarded = [floor is not None and any(isinstance(item, ManipulabilityBarrier) and item.min_value == floor
                                         and (item.frame, item.rows, item.joints) == watched_measure
                                         for item in scenario.constraints)
               for scenario, _ in runs]
    return ManipulabilityTrace(first.frame, first.rows, floor, series, guarded, [result.stride for _, result in runs])


@dataclass
class CollisionTrace:
    """The smallest signed distance between the collision pairs of the first
    :class:`~wbc.CollisionAvoidance` found in the scenarios, in every run of the same robot (with
    or without that constraint), and its margin ``min_distance``."""

    margin: float  #: [m] the constraint's min_distance
    detection_distance: float  #: [m] pairs farther apart are not measured
    #: one (R+1,) array per run [m], at each recorded configuration (inf: no pair within the
    #: detection distance); None for a run of another robot
    series: list[NDArray[np.float64] | None]
    strides: list[int]  #: per run, the ticks per recorded row (RunResult.stride)

    def summary(self, run: int) -> dict[str, float]:
        """The smallest distance of run ``run`` and the margin (empty for a run of another robot)."""
        series = self.series[run]
        if series is None:
            return {}
        summary = {"collision_distance_min_m": float(series.min()), "collision_margin_m": self.margin}
        if self.strides[run] > 1:
            summary["collision_sampled_every_ticks"] = self.strides[run]
        return summary


def collision_traces(runs: Sequence[tuple[Scenario, RunResult]]) -> CollisionTrace | None:
    """The distances of :class:`CollisionTrace` (None when no scenario has collision avoidance):
    the same pairs and obstacles measured at every recorded configuration of each run of that
    robot, as a with/without comparison needs."""
    found = next(((scenario.robot.name, item) for scenario, _ in runs for item in scenario.constraints
                  if isinstance(item, CollisionAvoidance)), None)
    if found is None:
        return None
    robot_name, avoidance = found
    series: list[NDArray[np.float64] | None] = []
    for scenario, result in runs:
        if scenario.robot.name != robot_name:
            series.append(None)
            continue
        distances = Distances(scenario.robot, avoidance.obstacles, avoidance.self_collision,
                              avoidance.detection_distance)
        pairs = distances.buffers()
        smallest = []
        for q in result.q:
            count = distances.compute(q, pairs)
            smallest.append(float(pairs.distance[:count].min()) if count else np.inf)
        series.append(np.array(smallest))
    return CollisionTrace(avoidance.min_distance, avoidance.detection_distance, series,
                          [result.stride for _, result in runs])

def posture_traces(runs: Sequence[tuple[Scenario, RunResult]]) -> list[NDArray[np.float64] | None] | None:
    """When some scenario has priority levels: the error ``|q* (-) q|`` of the first PostureTask
    of every run at each recorded configuration (one (T+1,) array per run, None for a run
    without one) -- how far the posture got in the null space, next to the same stack weighted;
    None when no scenario has levels."""
    if not any(scenario.levels for scenario, _ in runs):
        return None
    series: list[NDArray[np.float64] | None] = []
    for scenario, result in runs:
        task = next((task for task in scenario.tasks if isinstance(task, PostureTask)), None)
        if task is None:
            series.append(None)
            continue
        data, model = task.bind(scenario.robot), scenario.robot.model
        series.append(np.array([np.linalg.norm(pin.difference(model, q, data.target)[data.indices])
                                for q in result.q]))
    return series


def _true_error(robot: Robot, task: FrameTask | PositionTask, q: NDArray[np.float64]) -> NDArray[np.float64]:
    """The error of the reference ``task`` at the true configuration ``q`` (position;
    orientation), against the target of the tick."""
    pose = robot.frame_pose(q, task.frame)
    target = task.target
    if target.shape == (3,):
        return target - pose[:3, 3]
    return np.concatenate([target[:3, 3] - pose[:3, 3], pin.log3(target[:3, :3] @ pose[:3, :3].T)])


def wheel_ratio(robot: Robot, qs: NDArray[np.float64], vs: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """(T, n_wheels) ``|u_i| / u_max`` of a wheeled base with a declared speed limit, else None."""
    wheels = robot.base.wheels
    if wheels is None or not np.isfinite(wheels.max_speed):
        return None
    return np.abs(robot.base.twist(qs, vs) @ wheels.inverse_matrix().T) / wheels.max_speed


def lateral_slip(robot: Robot, qs: NDArray[np.float64], vs: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """(T,) largest no-slip residual ``|N t|`` [m/s] of a nonholonomic base (the sideways speed
    of a unicycle or synchro drive), else None."""
    if not robot.base.is_nonholonomic:
        return None
    return np.max(np.abs(robot.base.twist(qs, vs) @ robot.base.no_slip_rows().matrix.T), axis=1)


def position_violation(robot: Robot, qs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per row of ``qs``: largest distance outside the position limits (0 inside)."""
    with np.errstate(invalid="ignore"):
        above = np.where(np.isfinite(robot.upper), qs - robot.upper, 0.0)
        below = np.where(np.isfinite(robot.lower), robot.lower - qs, 0.0)
    return np.max(np.maximum(np.maximum(above, below), 0.0), axis=1)


def velocity_ratio(robot: Robot, qs: NDArray[np.float64], vs: NDArray[np.float64]) -> NDArray[np.float64]:
    """``|v_i| / limit_i`` per tick; mobile-base linear speeds are taken in the base frame."""
    speeds = np.abs(vs)
    if robot.base.is_mobile:
        x, y, _ = robot.base.indices
        twists = robot.base.twist(qs, vs)
        speeds[:, x], speeds[:, y] = np.abs(twists[:, 0]), np.abs(twists[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(robot.velocity_limit), speeds / robot.velocity_limit, 0.0)
