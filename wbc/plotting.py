"""Figure of closed-loop runs: tracking error, joint speeds against limits, latency, paths,
and the manipulability m(t) when a scenario watches it. Several runs are overlaid."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .closed_loop import ManipulabilityTrace, RunResult, manipulability_traces  # noqa: F401 (was defined here)


def plot_run(result: RunResult, path: str | Path, joint_names: list[str] | None = None) -> Path:
    """Figure of one run (see :func:`plot_runs`)."""
    return plot_runs([result], path, joint_names)


def plot_runs(results: Sequence[RunResult], path: str | Path, joint_names: list[str] | None = None,
              trace: ManipulabilityTrace | None = None) -> Path:
    """Write a PNG overlaying ``results`` and return its path (needs matplotlib: ``pip install wbc[plot]``).

    One run shows every joint's speed ratio; several show the largest ratio of each run.
    With a ``trace`` a fifth panel shows m(t) and the barrier floor m_min.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    layout = [["error", "speed"], ["latency", "base"]] + ([["m", "m"]] if trace is not None else [])
    fig, axes = plt.subplot_mosaic(layout, figsize=(12, 4 * len(layout)), constrained_layout=True)
    several = len(results) > 1
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]

    ax = axes["error"]
    for k, result in enumerate(results):
        prefix, color = (f"{result.scenario}: ", colors[k % len(colors)]) if several else ("", None)
        ax.semilogy(result.time, np.maximum(result.position_error, 1e-12) * 1e3, color=color,
                    label=f"{prefix}position [mm]")
        ax.semilogy(result.time, np.maximum(result.orientation_error, 1e-12) * 1e3, color=color,
                    ls="--" if several else "-", label=f"{prefix}orientation [mrad]")
    ax.set(title="Tracking error", xlabel="time [s]")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)

    ax = axes["speed"]
    if several:
        for k, result in enumerate(results):
            ax.plot(result.time, result.velocity_ratio.max(axis=1), lw=1, color=colors[k % len(colors)],
                    label=f"{result.scenario}: max over joints")
    else:
        result = results[0]
        names = joint_names or [f"v{i}" for i in range(result.velocity_ratio.shape[1])]
        for i, name in enumerate(names):
            ax.plot(result.time, result.velocity_ratio[:, i], lw=1, label=name)
    ax.axhline(1.0, color="k", ls="--", lw=1, label="limit")
    ax.set(title="|v| / velocity limit", xlabel="time [s]", ylim=(0, 1.15))
    ax.legend(fontsize=7, ncol=1 if several else 3)
    ax.grid(True, alpha=0.3)

    ax = axes["latency"]
    for k, result in enumerate(results):
        prefix, color = (f"{result.scenario}: ", colors[k % len(colors)]) if several else ("", None)
        ax.plot(result.time, result.tick_time * 1e6, lw=0.6, color=color, label=f"{prefix}tick (step)")
        ax.plot(result.time, result.solve_time * 1e6, lw=0.6, color=color, ls=":" if several else "-",
                label=f"{prefix}solve ({result.solver})")
    top = max(np.percentile(result.tick_time, 99.5) for result in results)
    ax.set(title="Latency", xlabel="time [s]", ylabel="[µs]", ylim=(0, top * 1.5e6))
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)

    ax = axes["base"]
    for k, result in enumerate(results):
        prefix, color = (f"{result.scenario}: ", colors[k % len(colors)]) if several else ("", None)
        if result.base_path is not None:
            ax.plot(result.base_path[:, 0], result.base_path[:, 1], color=color, label=f"{prefix}base")
        if result.tool_path is not None:
            ax.plot(result.tool_path[:, 0], result.tool_path[:, 1], color=color, ls="--", label=f"{prefix}tool")
    ax.set(title="Paths (top view, world x-y)", xlabel="x [m]", ylabel="y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)

    if trace is not None:
        ax = axes["m"]
        for k, (result, series) in enumerate(zip(results, trace.series, strict=False)):
            if series is None:
                continue
            ax.plot(np.arange(series.size) * result.dt, series, color=colors[k % len(colors)],
                    label=result.scenario)
        if trace.min_value is not None:
            ax.axhline(trace.min_value, color="k", ls="--", lw=1, label=f"m_min = {trace.min_value:g}")
        ax.set(title=f"Manipulability m of '{trace.frame}' ({trace.rows} rows)", xlabel="time [s]",
               ylim=(0, None))
        ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)

    names = ", ".join(result.scenario for result in results)
    fig.suptitle(f"{names} — {results[0].solver}, dt = {results[0].dt * 1e3:.0f} ms")
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
