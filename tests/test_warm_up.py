"""The warm-up at build (wbc.control.warm_up): a throwaway twin ticks, the controller does not change.

A controller built with ``warm_up=True`` (the default) must command exactly what one built
with ``warm_up=False`` commands, tick after tick, with the same diagnostics: the oracle is the
controller without the warm-up, on shipped scenarios covering one QP, strict priorities,
AccelerationLimits, collision avoidance, a nonholonomic base (plain and reduced) and a
qpsolvers backend. The warm-up must also run (not be skipped) where the README's loop builds the
controller before its first target, and never raise nor hide an error of the first tick.
"""

from __future__ import annotations

import copy
import threading

import numpy as np
import pytest

import wbc
from wbc.app.scenario import load_scenario
from wbc.control import controller as controller_module
from wbc.control.warm_up import WARM_UP_TICKS, warm_up_twin

TICKS = 60

#: (scenario, overrides of the controller's arguments)
CASES = [
    ("youbot_circle", {}),
    ("youbot_circle", {"solver": "quadprog"}),
    ("youbot_priorities", {}),
    ("youbot_reach_accel", {}),
    ("youbot_obstacle", {}),
    ("deluca_parking", {}),
    ("deluca_parking", {"reduced": True}),
    ("puma_wrist_pass", {}),
]


def _controller(name: str, overrides: dict, warm_up: bool) -> tuple[wbc.Controller, object]:
    """A fresh scenario (its own items) and its controller, warmed up or not."""
    scenario = load_scenario(name)
    arguments = dict(solver=scenario.solver, dt=scenario.dt, damping=scenario.damping, reduced=scenario.reduced,
                     lm_damping=scenario.lm_damping)
    controller = wbc.Controller(scenario.robot, scenario.task_levels, scenario.constraints,
                                **{**arguments, **overrides}, warm_up=False)
    if warm_up:
        assert warm_up_twin(controller._twin)  # what every build runs
    return controller, scenario


def _run(name: str, overrides: dict, warm_up: bool) -> list[tuple]:
    """Commands and diagnostics (all but the timings) of TICKS closed-loop ticks."""
    controller, scenario = _controller(name, overrides, warm_up)
    q, records = scenario.q0.copy(), []
    for k in range(TICKS):
        if scenario.reference is not None:
            scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
        v = controller.step(q)
        last = controller.last
        records.append((v.copy(), last.tick, last.solver, last.outcome, last.status, last.success, last.v.copy(),
                        last.u.copy(), last.task_errors, last.max_violation, last.active_constraints,
                        last.conflicts, controller.context.previous.copy()))
        q = scenario.robot.integrate(q, v, scenario.dt)
    return records


@pytest.mark.parametrize(("name", "overrides"), CASES, ids=[f"{n}-{'-'.join(map(str, o.values())) or 'plain'}"
                                                              for n, o in CASES])
def test_a_warmed_controller_commands_exactly_what_a_cold_one_does(name, overrides):
    warmed, cold = _run(name, overrides, True), _run(name, overrides, False)
    for tick, (a, b) in enumerate(zip(warmed, cold, strict=True)):
        for field, (x, y) in enumerate(zip(a, b, strict=True)):
            if isinstance(x, np.ndarray):
                assert x.tobytes() == y.tobytes(), (tick, field, x, y)  # bitwise
            else:
                assert x == y, (tick, field, x, y)


def test_every_build_warms_up_unless_told_not_to(youbot, monkeypatch):
    """Every build: what is warmed is also the CPU's caches, which building another controller
    (a scenario's check, say) evicts again."""
    twins = []
    monkeypatch.setattr(controller_module, "warm_up_twin", lambda make_twin: twins.append(make_twin.__self__) or True)

    def build(**keywords):
        return wbc.Controller(youbot, [wbc.FrameTask("ee"), wbc.KineticEnergyRegularization(1e-3)],
                              [wbc.JointVelocityLimits()], **keywords)

    build(warm_up=False)
    assert twins == []
    first, second = build(), build()
    assert twins == [first, second]
    copy.deepcopy(first)  # a copy does not
    assert twins == [first, second]


def test_the_warm_up_runs_before_the_first_target_and_leaves_the_task_without_one(youbot):
    """The README's loop builds the controller, then sets the target in the loop."""
    ee = wbc.FrameTask("ee", gain=0.5)
    controller = wbc.Controller(youbot, [ee, wbc.KineticEnergyRegularization(1e-3)], [wbc.JointVelocityLimits()],
                                warm_up=False)
    assert warm_up_twin(controller._twin)
    with pytest.raises(wbc.InvalidInputError, match="no target set"):  # still the user's error to see
        controller.step(youbot.neutral())


class _LockedTask(wbc.PostureTask):
    """A task holding something that cannot be deep-copied (so its controller cannot be copied)."""

    def __init__(self) -> None:
        super().__init__(1e-2)
        self._lock = threading.Lock()


class _NeverReady(wbc.PostureTask):
    def check_ready(self) -> None:
        raise wbc.InvalidInputError("NeverReady: not ready yet")


def test_a_controller_that_cannot_be_copied_builds_and_ticks_without_the_warm_up(youbot):
    task = _LockedTask()
    controller = wbc.Controller(youbot, [task], [wbc.JointVelocityLimits()])
    assert not warm_up_twin(controller._twin)
    cold = wbc.Controller(youbot, [task], [wbc.JointVelocityLimits()], warm_up=False)
    q = youbot.random_configuration(np.random.default_rng(3))
    assert controller.step(q).tobytes() == cold.step(q).tobytes()


def test_a_task_that_is_not_ready_still_raises_at_the_first_tick(youbot):
    controller = wbc.Controller(youbot, [_NeverReady(1e-2)])  # the warm-up fails quietly
    with pytest.raises(wbc.InvalidInputError, match="not ready yet"):
        controller.step(youbot.neutral())


class _Sending(wbc.Controller):
    """A controller that acts on the world in its step (sends the command somewhere)."""

    def step(self, q, v_measured=None):
        v = super().step(q, v_measured)
        SENT.append(v)
        return v


SENT: list = []


def test_the_twin_of_a_subclass_never_runs_the_subclass_step(youbot):
    SENT.clear()
    controller = _Sending(youbot, [wbc.PostureTask(1e-2), wbc.KineticEnergyRegularization(1e-3)])
    assert SENT == []  # built (and warmed) without sending anything
    assert warm_up_twin(controller._twin) and SENT == []  # (the twin did tick)
    controller.step(youbot.neutral())
    assert len(SENT) == 1


def test_warm_up_must_be_a_bool(youbot):
    with pytest.raises(wbc.InvalidInputError, match="warm_up"):
        wbc.Controller(youbot, [wbc.PostureTask(1e-2)], warm_up="no")


class _CountingTwin:
    """A twin that counts its ticks (warm_up_twin's Steppable)."""

    def __init__(self, robot) -> None:
        self.robot, self.tasks, self.q = robot, [], []

    def step(self, q):
        self.q.append(q.copy())
        return np.zeros(self.robot.nv)


def test_the_twin_ticks_past_the_interpreters_warm_up(youbot):
    """CPython 3.11 specialises a function's bytecode after its 8th call: the twin's ticks must
    reach past it at build, within the position limits."""
    twin = _CountingTwin(youbot)
    assert warm_up_twin(lambda: twin)
    assert len(twin.q) == WARM_UP_TICKS and WARM_UP_TICKS > 8
    assert all(np.all(youbot.lower <= q) and np.all(q <= youbot.upper) for q in twin.q)
