"""``last.conflicts`` (issue 24 §9): the constraints that cannot hold together, named.

Known conflicts are built from rows pushing joints beyond their speed limits; random ones are
checked against an independent LP (scipy's HiGHS): the named set is infeasible and removing any
one of its members makes it feasible."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

import wbc
from wbc.constraints.constraint import Constraint, ConstraintData

YOUBOT = wbc.load_robot("youbot")
HOME = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])
NAMES = {name: i for i, name in enumerate(["x", "y", "heading", "arm_joint_1", "arm_joint_2", "arm_joint_3",
                                           "arm_joint_4", "arm_joint_5"])}


class Rows(Constraint, ConstraintData):
    """Inequality rows ``G v <= h`` (hard or soft), fixed."""

    def __init__(self, G, h, hard=True, name="Rows"):
        super().__init__(name)
        self.G, self.h, self.hard = np.atleast_2d(np.asarray(G, float)), np.atleast_1d(np.asarray(h, float)), hard
        self.n_inequalities = len(self.h)

    def write_static(self, rows):
        rows.G[...], rows.h[...] = self.G, self.h

    def compute(self, kin, dt, rows):
        pass


def push(joint: int, speed: float) -> tuple[np.ndarray, float]:
    """The row ``v[joint] >= speed``."""
    row = np.zeros(8)
    row[joint] = -1.0
    return row, -speed


def controller(*extra: Constraint, **options) -> wbc.Controller:
    limits = [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()]
    return wbc.Controller(YOUBOT, [wbc.PostureTask(1.0)], limits + list(extra), **options)


@pytest.mark.parametrize("hard", [True, False])
def test_a_row_beyond_a_speed_limit_is_named_with_that_limit(hard):
    G, h = push(4, 3.0)  # arm_joint_2 limit 1.57 rad/s
    c = controller(Rows(G, h, hard, "Push"))
    c.step(HOME)
    assert not c.last.success
    assert c.last.outcome is (wbc.Outcome.ZERO if hard else wbc.Outcome.ELASTIC)
    assert sorted(c.last.conflicts) == ["JointVelocityLimits: arm_joint_2 upper", "Push: row 0"]


def test_a_sum_beyond_two_limits_names_both_limits():
    row = np.zeros(8)
    row[[3, 4]] = -1.0  # v3 + v4 >= 3.5 > 1.571 + 1.571
    c = controller(Rows(row, -3.5, name="Sum"))
    c.step(HOME)
    assert sorted(c.last.conflicts) == ["JointVelocityLimits: arm_joint_1 upper",
                                        "JointVelocityLimits: arm_joint_2 upper", "Sum: row 0"]


def test_rows_that_conflict_only_with_each_other_are_named_without_the_limits():
    row = np.zeros(8)
    row[5] = 1.0
    c = controller(Rows([row, -row], [-0.2, -0.1], name="Pair"))  # v5 <= -0.2 and v5 >= 0.1
    c.step(HOME)
    assert sorted(c.last.conflicts) == ["Pair: row 0", "Pair: row 1"]


def test_of_two_separate_conflicts_one_is_named_whole():
    first, second = push(4, 3.0), push(6, -3.0)
    second = (-second[0], -3.0)  # v6 <= -3 below the lower limit -1.57
    c = controller(Rows([first[0], second[0]], [first[1], second[1]], name="Two"))
    c.step(HOME)
    assert sorted(c.last.conflicts) in (["JointVelocityLimits: arm_joint_2 upper", "Two: row 0"],
                                        ["JointVelocityLimits: arm_joint_4 lower", "Two: row 1"])


def test_a_tick_that_succeeds_or_fails_without_a_conflict_names_none():
    c = controller()
    c.step(HOME)
    assert c.last.success and c.last.conflicts == []
    G, h = push(4, 1.0)  # within the limit: feasible
    c = controller(Rows(G, h, name="Fine"))
    c.step(HOME)
    assert c.last.success and c.last.conflicts == []
    nan_rows = controller(Rows(G, np.nan, name="Nan"))
    nan_rows.step(HOME)
    assert nan_rows.last.outcome is wbc.Outcome.ZERO and nan_rows.last.conflicts == []


def test_conflicts_with_priority_levels_and_in_the_reduced_form():
    G, h = push(4, 3.0)
    ee = wbc.FrameTask("ee", gain=0.5)
    ee.set_target(YOUBOT.frame_pose(HOME, "ee"))
    levels = wbc.Controller(YOUBOT, [[ee], [wbc.PostureTask(1.0)]],
                            [wbc.JointVelocityLimits(), Rows(G, h, name="Push")])
    levels.step(HOME)
    assert sorted(levels.last.conflicts) == ["JointVelocityLimits: arm_joint_2 upper", "Push: row 0"]
    deluca = wbc.load_robot("deluca_mm")  # synchro drive: inputs (v, omega) and the arm
    row = np.zeros(deluca.nv)
    row[deluca.base.indices[2]] = -1.0  # heading rate >= 10 rad/s, beyond its limit
    q = deluca.neutral()
    reduced = wbc.Controller(deluca, [wbc.PostureTask(1.0)], [wbc.JointVelocityLimits(), Rows(row, -10.0, name="Spin")],
                             reduced=True)
    reduced.step(q)
    assert not reduced.last.success
    assert len(reduced.last.conflicts) == 2 and "Spin: row 0" in reduced.last.conflicts
    assert any(name.startswith("JointVelocityLimits:") for name in reduced.last.conflicts)


def _rows_of(labels: list[str], G: np.ndarray, h: np.ndarray, limit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows the labels name (the test's own rows, or a joint's speed limit), written out."""
    rows, bounds = [], []
    for label in labels:
        owner, what = label.split(": ")
        if owner == "Random":
            i = int(what.split()[1])
            rows.append(G[i]), bounds.append(h[i])
        else:
            assert owner == "JointVelocityLimits", label
            name, side = what.split()
            j, row = NAMES[name], np.zeros(8)
            row[j] = 1.0 if side == "upper" else -1.0
            rows.append(row), bounds.append(limit[j])
    return np.array(rows), np.array(bounds)


def _feasible(rows: np.ndarray, bounds: np.ndarray) -> bool:
    result = linprog(np.zeros(rows.shape[1]), A_ub=rows, b_ub=bounds, bounds=[(None, None)] * rows.shape[1],
                     method="highs")
    assert result.status in (0, 2), result.message
    return result.status == 0


@pytest.mark.parametrize("seed", range(12))
def test_random_conflicts_are_irreducible_by_an_independent_lp(seed):
    rng = np.random.default_rng(seed)
    k = rng.integers(2, 6)
    G = np.zeros((k, 8))
    G[:, 3:] = rng.standard_normal((k, 5))  # arm joints only: the base-frame limits stay out
    h = rng.uniform(-6.0, 0.5, k)  # some rows demand speeds beyond the limits
    limit = YOUBOT.velocity_limit
    c = wbc.Controller(YOUBOT, [wbc.PostureTask(1.0)], [wbc.JointVelocityLimits(), Rows(G, h, name="Random")])
    c.step(HOME)
    everything = np.vstack([G[:, 3:], np.eye(5), -np.eye(5)]), np.concatenate([h, limit[3:], limit[3:]])
    if _feasible(*everything):
        assert c.last.success and c.last.conflicts == []
        return
    named = c.last.conflicts
    assert named and not c.last.success
    rows, bounds = _rows_of(named, G, h, limit)
    assert not _feasible(rows, bounds)
    for i in range(len(named)):
        keep = np.arange(len(named)) != i
        assert _feasible(rows[keep], bounds[keep]), f"{named[i]} is not needed for the conflict {named}"


class Toggle(Constraint, ConstraintData):
    """``v[4] >= 3`` (beyond its limit) on the ticks listed, nothing on the others."""

    n_inequalities = 1

    def __init__(self, ticks):
        super().__init__("Toggle")
        self.ticks, self._count = set(ticks), 0

    def compute(self, kin, dt, rows):
        self._count += 1
        rows.G[0, 4] = -1.0 if self._count in self.ticks else 0.0
        rows.h[0] = -3.0 if self._count in self.ticks else 0.0


def test_a_run_records_each_episode_of_conflict_once_and_wbc_run_prints_it():
    from wbc.app.cli import _conflicts, format_summary
    from wbc.app.closed_loop import ConflictEpisode, run
    from wbc.app.scenario import load_scenario

    scenario = load_scenario("youbot_reach")
    base = scenario.make_controller("daqp")
    toggle = Toggle([3, 4, 5, 10, 11])
    controller = wbc.Controller(scenario.robot, base.tasks, [*base.constraints, toggle])
    result = run(scenario, controller=controller, duration=20 * scenario.dt)
    named = ("JointVelocityLimits: arm_joint_2 upper", "Toggle: row 0")
    assert result.fallback_ticks == 5
    assert [(e.tick, tuple(sorted(e.constraints))) for e in result.conflicts] == [(3, named), (10, named)]
    summary = result.summary() | _conflicts(result)
    text = format_summary(scenario.name, "daqp", summary | {"loop": "kinematic"})
    lines = [line for line in text.splitlines() if "constraints in conflict" in line]
    assert len(lines) == 2 and "tick 3 " in lines[0] and "tick 10 " in lines[1]
    assert all("Toggle: row 0" in line and "arm_joint_2 upper" in line for line in lines)
    assert isinstance(result.conflicts[0], ConflictEpisode)


def test_a_collision_row_that_asks_more_than_the_limits_allow_is_named_by_its_pair():
    """A sphere inside the margin of the gripper, pushed out at full gain (d_min - d in one tick)
    faster than the joints and wheels can move: the collision row and the limits it meets."""
    q = HOME
    ee = wbc.FrameTask("ee", gain=0.5)
    ee.set_target(YOUBOT.frame_pose(q, "ee"))
    sphere = wbc.Sphere(YOUBOT.frame_pose(q, "ee")[:3, 3] + [0.0, 0.0, 0.05], 0.04)
    avoidance = wbc.CollisionAvoidance(obstacles=[sphere], self_collision=False, min_distance=0.05, gain=1.0)
    c = wbc.Controller(YOUBOT, [ee, wbc.PostureTask(1e-3)],
                       [wbc.JointVelocityLimits(), wbc.MecanumWheelLimits(), avoidance])
    c.step(q)
    assert c.last.outcome is wbc.Outcome.ELASTIC  # the collision rows are soft: they yield
    named = c.last.conflicts
    pairs = [name for name in named if name.startswith("CollisionAvoidance: ")]
    assert pairs and all(name.endswith("↔sphere0") for name in pairs)
    assert any(name.startswith(("JointVelocityLimits: ", "MecanumWheelLimits: ")) for name in named)
    assert all("row" not in name for name in pairs)  # this tick's pairs, not capacity slots
