"""The tick's context (issue 23 §3): ``step(q, v_measured=None)``, and items that read the
previous command and the measured velocity through ``use_context`` (wbc.model.tick_context).

The reader below is a Python constraint bounding the change of the command per tick,
``|v - previous| <= A_MAX dt`` (the shape of issue 24's acceleration limits, not a shipped item):
its bounds hold in closed loop only if the context's ``previous`` is the command ``step``
returned the tick before."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

import wbc
from wbc.constraints.constraint import ConstraintData, ConstraintRows
from wbc.model.kinematics import Kinematics
from wbc.model.tick_context import TickContext

YOUBOT = wbc.load_robot("youbot")
A_MAX = 2.0  #: [unit/s^2] the reader's bound on the change of the command


class RateLimitData(ConstraintData):
    """``previous - A_MAX dt <= v <= previous + A_MAX dt`` (no bound before the first tick); it
    records what it read from the context."""

    has_bounds = True

    def __init__(self, constraint: RateLimit) -> None:
        super().__init__(constraint)
        self.seen: list[tuple[np.ndarray | None, np.ndarray | None, float]] = []

    def use_context(self, context: TickContext) -> None:
        self.context = context

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        context = self.context
        assert context.kinematics is kin and context.dt == dt
        previous, measured = context.previous, context.measured
        self.seen.append((None if previous is None else previous.copy(),
                          None if measured is None else measured.copy(), context.dt))
        if previous is None:
            rows.lower[:], rows.upper[:] = -np.inf, np.inf
        else:
            rows.lower[:], rows.upper[:] = previous - A_MAX * dt, previous + A_MAX * dt


class RateLimit(wbc.Constraint):
    """The specification of :class:`RateLimitData` (one data per controller)."""

    has_bounds = True

    def bind(self, robot: wbc.Robot) -> RateLimitData:
        return RateLimitData(self)


def _controller(limit: RateLimit, **options) -> wbc.Controller:
    ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.1, gain=0.5)
    pose = YOUBOT.frame_pose(YOUBOT.neutral(), "ee").copy()
    pose[:3, 3] += (0.3, -0.2, 0.1)
    ee.set_target(pose)
    return wbc.Controller(YOUBOT, [ee, wbc.PostureTask(cost=1e-3)], [wbc.JointVelocityLimits(), limit], **options)


def test_an_item_reads_the_previous_command_and_the_measured_velocity():
    controller = _controller(RateLimit())
    reader = controller.data(controller.constraints[1])
    rng = np.random.default_rng(5)
    q, commands, measured = YOUBOT.neutral(), [], []
    for _ in range(30):
        measured.append(rng.standard_normal(YOUBOT.nv))
        v = controller.step(q, v_measured=measured[-1])
        commands.append(v.copy())
        q = YOUBOT.integrate(q, v, controller.dt)
    assert reader.seen[0][0] is None  # no previous command at the first tick
    for k in range(1, 30):
        np.testing.assert_array_equal(reader.seen[k][0], commands[k - 1])
    for k in range(30):
        np.testing.assert_array_equal(reader.seen[k][1], measured[k])
        assert reader.seen[k][2] == controller.dt
    steps = np.abs(np.diff(np.array(commands), axis=0))
    assert steps.max() <= A_MAX * controller.dt * (1 + 1e-9)  # the reader's bounds held
    assert steps.max() >= 0.5 * A_MAX * controller.dt  # ... and acted (a far target)


def test_the_measured_velocity_is_this_ticks_only():
    controller = _controller(RateLimit())
    reader = controller.data(controller.constraints[1])
    q = YOUBOT.neutral()
    measured = np.full(YOUBOT.nv, 0.25)
    controller.step(q, measured)
    measured[:] = 7.0  # the context holds a copy
    np.testing.assert_array_equal(reader.seen[-1][1], np.full(YOUBOT.nv, 0.25))
    controller.step(q)
    assert reader.seen[-1][1] is None and controller.context.measured is None
    controller.step(q, list(np.zeros(YOUBOT.nv)))  # any vector-like input
    np.testing.assert_array_equal(controller.context.measured, np.zeros(YOUBOT.nv))


@pytest.mark.parametrize("bad", [np.zeros(3), np.full(YOUBOT.nv, np.nan), "fast", np.full(YOUBOT.nv, np.inf)])
def test_a_bad_measured_velocity_is_refused_by_name(bad):
    controller = _controller(RateLimit())
    with pytest.raises(wbc.InvalidInputError, match="v_measured"):
        controller.step(YOUBOT.neutral(), bad)


def test_the_context_is_the_controllers_and_the_buffers():
    controller = _controller(RateLimit())
    assert controller._buffers.context is controller.context
    assert controller.context.kinematics is controller.kinematics
    v = controller.step(YOUBOT.neutral())
    assert controller.context.previous is v


@pytest.mark.parametrize("duplicate", [copy.copy, copy.deepcopy, lambda c: pickle.loads(pickle.dumps(c))],
                         ids=["copy", "deepcopy", "pickle"])
def test_a_copy_carries_the_previous_command(duplicate):
    """The previous command is warm state: a copy's reader starts from the original's."""
    original = _controller(RateLimit())
    q = YOUBOT.neutral()
    for _ in range(3):
        q = YOUBOT.integrate(q, original.step(q), original.dt)
    twin = duplicate(original)
    np.testing.assert_array_equal(twin.context.previous, original.context.previous)
    assert twin.context is not original.context
    np.testing.assert_array_equal(twin.step(q), original.step(q))
