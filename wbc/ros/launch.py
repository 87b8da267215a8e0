"""``wbc ros SCENARIO --config FILE``: load the scenario and the node's configuration, join
the DDS domain of the environment (``ROS_DOMAIN_ID``, ``CYCLONEDDS_URI``, ...: see
:mod:`wbc.ros.dds`), run the node until SIGINT or SIGTERM (or ``--duration``), write the
zero command, wait briefly for the robot to acknowledge it, print the summary."""

from __future__ import annotations

import json
import sys
import threading
from pathlib import Path
from typing import Any

from ..app.scenario import load_scenario
from .config import load_config
from .dds import Participant
from .node import Node, stop_on_signals

FLUSH_TIMEOUT = 0.5  #: [s] at most, waiting at exit for the robot to acknowledge the zero command


def launch(scenario: str | Path, config: str | Path, duration: float | None = None,
           solver: str | None = None) -> dict[str, Any]:
    """Run the node of ``scenario`` (file or shipped name) with ``config`` (file or shipped name);
    its summary (:meth:`wbc.ros.node.Node.summary`).

    Raises:
        ScenarioError, RosConfigError, RosError: a bad scenario, configuration or DDS setup.
    """
    loaded = load_scenario(scenario)
    node_config = load_config(config, loaded.robot, loaded.tasks)
    participant = Participant()
    stop = threading.Event()
    restore = stop_on_signals(stop)
    try:
        node = Node(loaded, node_config, participant, loaded.make_controller(solver))
        summary = node.run(stop, duration)
        summary["zero_acknowledged"] = node.commands.flush(FLUSH_TIMEOUT)
    finally:
        restore()
        participant.close()
    return summary


def format_summary(summary: dict[str, Any]) -> str:
    """The summary as ``wbc ros`` prints it: one ``key: value`` line each."""
    return "\n".join(f"  {key}: {value:.6g}" if isinstance(value, float) else f"  {key}: {value}"
                     for key, value in summary.items())


def main(scenario: str, config: str, duration: float | None, solver: str | None, as_json: bool) -> int:
    """The command: run, then print the summary (as JSON on stdout with ``as_json``)."""
    summary = launch(scenario, config, duration, solver)
    if as_json:
        print(json.dumps(summary, indent=2))
    else:
        print("wbc ros: stopped; zero command written\n" + format_summary(summary), file=sys.stderr)
    return 0
