"""Figure of a closed-loop run: tracking error, joint speeds against limits, latency, paths."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .closed_loop import RunResult


def plot_run(result: RunResult, path: str | Path, joint_names: list[str] | None = None) -> Path:
    """Write a 4-panel PNG and return its path (needs matplotlib: ``pip install wbc[plot]``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 8), constrained_layout=True)
    t = result.time
    ax = axes[0, 0]
    ax.semilogy(t, np.maximum(result.position_error, 1e-12) * 1e3, label="position [mm]")
    ax.semilogy(t, np.maximum(result.orientation_error, 1e-12) * 1e3, label="orientation [mrad]")
    ax.set(title="Tracking error", xlabel="time [s]")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)

    ax = axes[0, 1]
    names = joint_names or [f"v{i}" for i in range(result.velocity_ratio.shape[1])]
    for i, name in enumerate(names):
        ax.plot(t, result.velocity_ratio[:, i], lw=1, label=name)
    ax.axhline(1.0, color="k", ls="--", lw=1, label="limit")
    ax.set(title="|v| / velocity limit", xlabel="time [s]", ylim=(0, 1.15))
    ax.legend(fontsize=7, ncol=3)
    ax.grid(True, alpha=0.3)

    ax = axes[1, 0]
    ax.plot(t, result.tick_time * 1e6, lw=0.6, label="tick (step)")
    ax.plot(t, result.solve_time * 1e6, lw=0.6, label=f"solve ({result.solver})")
    ax.set(title="Latency", xlabel="time [s]", ylabel="[µs]",
           ylim=(0, np.percentile(result.tick_time, 99.5) * 1.5e6))
    ax.legend()
    ax.grid(True, alpha=0.3)

    ax = axes[1, 1]
    ax.plot(result.q[:, 0], result.q[:, 1], label="base (x, y)")
    ax.set(title="Base path (top view)", xlabel="x [m]", ylabel="y [m]", aspect="equal")
    ax.legend()
    ax.grid(True, alpha=0.3)

    fig.suptitle(f"{result.scenario} — {result.solver}, dt = {result.dt * 1e3:.0f} ms")
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
