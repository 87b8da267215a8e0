"""``[reference] type = "planned"`` of a scenario file (wbc.app.scenario): the keys and their plan.

    path = "line" | "arc"      # straight line or circular arc (then centre = [x, y, z] [m])
    duration = 6.0             # [s] of the rest-to-rest quintic timing of the whole path
    threshold = 1e-4           # singular region: singularity_measure <= threshold
    reroute = true             # false: the naive path, sampled and checked only
    margin = 2.0               # cuts where the measure < margin * threshold (planner docs)
    wrist = ["joint_4", "joint_5", "joint_6"]   # optional, for the flip diagnostics

The path starts at the frame's pose in the initial configuration and ends at the goal
pose of the reference (``configuration`` / ``position`` / ``rpy``, as for "line").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..core.errors import ScenarioError
from ..model.robot import Robot
from .paths import ArcPath, LinePath, Path
from .planner import MARGIN, Plan, plan


def plan_from_spec(spec: dict[str, Any], robot: Robot, frame: str, q0: np.ndarray, start: np.ndarray,
                   goal: np.ndarray) -> Plan:
    """Plan of a ``[reference]`` table; the keys above are consumed from ``spec``."""
    kind = spec.pop("path", "line")
    path: Path
    if kind == "line":
        path = LinePath(start, goal)
    elif kind == "arc":
        path = ArcPath(start, goal, spec.pop("centre"))
    else:
        raise ScenarioError(f"[reference] path {kind!r} unknown; known: line, arc")
    wrist = spec.pop("wrist", None)
    return plan(robot, path, q0, duration=spec.pop("duration"), threshold=spec.pop("threshold"), frame=frame,
                reroute=bool(spec.pop("reroute", True)), margin=spec.pop("margin", MARGIN),
                wrist=None if wrist is None else tuple(wrist))
