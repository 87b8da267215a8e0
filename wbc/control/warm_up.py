"""Warming a controller's code when it is built, so that its first tick runs warm.

The first tick of a process used to take 12-15x a steady tick (``python -m benchmarks.cold``):
not page faults nor lazy binding, but code and data run for the first time after the build
(Python's inline caches, numba's dispatch, the ops' callbacks, DAQP's solve). A throwaway
*twin* -- a deep copy of the controller, with copies of its robot, tasks, constraints and
solver and buffers, program and DAQP workspaces of its own -- ticks :data:`WARM_UP_TICKS` times
when the controller is built, as the controller's first and later ticks run: on the control loop's one-call native
path where the controller has it (the first tick checks the tasks first), else on the pipeline.
The controller itself is not touched: its tick counter, previous command, DAQP working sets,
items' targets and ``last`` stay as they were.

Every build warms its own twin: what the twin warms is also the CPU's caches, which building
another controller evicts again (warming only the first controller of each kind in a process
left the first tick of a scenario's controller -- built after the scenario's own check build --
at 6-10x a steady tick).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ..model.robot import Robot
from ..tasks.error_task import ErrorTask
from ..tasks.task import Task


class Steppable(Protocol):
    """What the warm-up uses of its twin (a :class:`~wbc.control.controller.Controller`)."""

    @property
    def robot(self) -> Robot: ...

    @property
    def tasks(self) -> Sequence[Task]: ...

    def step(self, q: NDArray[np.float64]) -> NDArray[np.float64]: ...


#: ticks of the twin: past CPython 3.11's warm-up of a function's bytecode (specialised after its 8th
#: call; code objects are shared by every controller, so the twin's calls count). With two, the
#: quickening fell into the controller's own 6th tick: 7.0-7.3 us against 2.9-3.3 us around it
#: (youbot_circle, fresh processes); with ten it happens at build (+~30 us of a ~3 ms build)
WARM_UP_TICKS = 10


def warm_up_twin(make_twin: Callable[[], Steppable]) -> bool:
    """Make a throwaway twin of a controller (``make_twin``: a deep copy, as a plain
    ``Controller`` -- a subclass's own ``step``, which may act on the world, never runs here)
    and tick it :data:`WARM_UP_TICKS` times at Pinocchio's neutral configuration clipped into the
    position limits; True when every tick ran.

    The twin's :class:`~wbc.tasks.error_task.ErrorTask` copies that still wait for their first
    target (``needs_target``) tick toward the one their constructor left (a finite default;
    the controller's own tasks keep waiting for theirs). The warm-up is best effort: a twin
    that cannot be made or ticked (an item that cannot be deep-copied, a custom task that is
    not ready) is dropped and False returned -- the controller's own first tick checks the
    tasks and raises as it would without the warm-up, so no error is hidden.
    """
    try:
        twin = make_twin()
        for task in twin.tasks:
            if isinstance(task, ErrorTask) and task.needs_target and not task._has_target:
                task._has_target = True  # (the twin's copy only)
        robot = twin.robot
        q = np.clip(robot.neutral(), robot.lower, robot.upper)
        for _ in range(WARM_UP_TICKS):  # the first as the controller's first tick, the others as its later ones
            twin.step(q)
    except Exception:  # noqa: BLE001 -- any failure only means no warm-up (see the docstring)
        return False
    return True
