"""Figure of docs/manipulability.md: the youBot stretch scenario without and with the barrier.

Regenerate from the repository root with::

    python docs/manipulability_figure.py            # writes docs/manipulability_stretch.png
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from wbc.app.closed_loop import RunResult, run, velocity_ratio
from wbc.app.plotting import manipulability_traces
from wbc.app.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = [ROOT / "tasks" / "youbot_stretch_no_barrier.toml", ROOT / "tasks" / "youbot_stretch.toml"]


def figure(runs: list[tuple[Scenario, RunResult]], path: str | Path) -> Path:
    """Three panels: m(t) with m_min, distance to theta2 = theta3 = 0, largest joint-speed ratio."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    trace = manipulability_traces(runs)
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4), constrained_layout=True)
    for (scenario, result), m in zip(runs, trace.series, strict=True):
        t = np.arange(m.size) * result.dt
        axes[0].plot(t, m, label=scenario.name)
        axes[1].plot(t, np.degrees(np.hypot(result.q[:, 4], result.q[:, 5])), label=scenario.name)
        axes[2].plot(result.time, velocity_ratio(scenario.robot, result.q[:-1], result.v).max(axis=1),
                     label=scenario.name)
    axes[0].axhline(trace.min_value, color="k", ls="--", lw=1, label=f"m_min = {trace.min_value:g}")
    axes[0].set(title="manipulability m (6x8 Jacobian of 'ee')", xlabel="time [s]", ylim=(0, None))
    axes[1].set(title="distance to θ2 = θ3 = 0 [deg]", xlabel="time [s]", ylim=(0, None))
    axes[2].axhline(1.0, color="k", ls="--", lw=1, label="speed limit")
    axes[2].set(title="largest |v_i| / limit_i", xlabel="time [s]", ylim=(0, 1.1))
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def main(argv: list[str]) -> int:
    out = Path(argv[0]) if argv else ROOT / "docs" / "manipulability_stretch.png"
    runs = [(scenario, run(scenario)) for scenario in map(load_scenario, SCENARIOS)]
    print(f"figure written to {figure(runs, out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
