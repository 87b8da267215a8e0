"""Figure of closed-loop runs: tracking errors, speeds against their limits (base, wheels and
arm apart), latency, paths, and the manipulability m(t) when a scenario watches it. Several
runs are overlaid, one colour each."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .closed_loop import RunResult, manipulability_traces, posture_traces
from .outputs import check_output, write_atomically
from .robot import Robot
from .scenario import Scenario

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

FLOOR_DECADES = 3  #: the error panels' log axes start this many decades below the median error
WHEEL_NAMES = {4: ["FL", "FR", "RL", "RR"], 2: ["left", "right"]}  #: wheel order of wbc.base
GRID_COLUMNS = 6  #: the figure's grid: 1, 2 or 3 panels per row
#: what :func:`plot_runs` writes, by suffix: matplotlib's formats but those that need more
#: than matplotlib and Pillow (.pgf needs LaTeX, .avif a Pillow built with AVIF)
PLOT_FORMATS = {".png": "PNG", ".pdf": "PDF", ".svg": "SVG", ".svgz": "SVG (gzip)", ".eps": "EPS", ".ps": "PostScript",
                ".jpg": "JPEG", ".jpeg": "JPEG", ".tif": "TIFF", ".tiff": "TIFF", ".webp": "WebP", ".gif": "GIF"}


@dataclass
class SpeedGroup:
    """Columns of a run's speed-ratio array shown together in one panel."""

    key: str  #: "base", "wheels" or "arm"
    title: str
    ylabel: str
    columns: list[int]  #: of ``velocity_ratio`` (base, arm) or ``wheel_ratio`` (wheels)
    labels: list[str]


def speed_groups(robot: Robot, result: RunResult) -> list[SpeedGroup]:
    """The speed panels of one run: the mobile base's twist (in the base frame), its wheels
    (if their speed is limited) and the other joints, each against its own limit."""
    names = robot.joint_names
    base = list(robot.base.indices) if robot.base.is_mobile else []
    groups = []
    if base:
        groups.append(SpeedGroup("base", "Base: |v| / limit (base frame)", "speed / limit", base,
                                 ["v_x forward", "v_y left", f"ω ({names[base[2]]})"]))
    if result.wheel_ratio is not None:
        count = result.wheel_ratio.shape[1]
        labels = WHEEL_NAMES.get(count, [f"wheel {i + 1}" for i in range(count)])
        groups.append(SpeedGroup("wheels", "Wheels: |u| / u_max", "speed / limit", list(range(count)), labels))
    joints = [i for i in range(robot.nv) if i not in base]
    if joints:
        title = "Arm joints: |v| / limit" if base else "Joints: |v| / limit"
        groups.append(SpeedGroup("arm", title, "speed / limit", joints, [names[i] for i in joints]))
    return groups


def log_floor(series: Sequence[np.ndarray], decades: int = FLOOR_DECADES) -> float | None:
    """Lower limit of a log axis for ``series``: a power of ten ``decades`` below the median of
    their positive values, or the smallest of them if that is higher; None if none is positive.
    Values below it are drawn on it, so an exact 0 or a 1e-12 does not stretch the axis."""
    values = np.concatenate([np.ravel(s) for s in series]) if series else np.zeros(0)
    positive = values[np.isfinite(values) & (values > 0)]
    if positive.size == 0:
        return None
    exponent = max(np.floor(np.log10(np.median(positive))) - decades, np.floor(np.log10(positive.min())))
    return float(10.0 ** exponent)


def plot_run(scenario: Scenario, result: RunResult, path: str | Path) -> Path:
    """Figure of one run (see :func:`plot_runs`)."""
    return plot_runs([(scenario, result)], path)


def plot_runs(runs: Sequence[tuple[Scenario, RunResult]], path: str | Path) -> Path:
    """Write the :func:`figure` of ``runs`` to ``path`` in the format its suffix names (one of
    :data:`PLOT_FORMATS`: .png, .pdf, .svg, ...), atomically: a temporary file in the same
    folder, renamed to ``path`` once complete; a missing folder is created. Returns the path
    (needs matplotlib: ``pip install wbc[plot]``). A path that cannot be written raises
    :class:`~wbc.outputs.OutputError` before the figure is drawn."""
    import matplotlib.pyplot as plt

    path = check_output(str(path), PLOT_FORMATS)
    fig = figure(runs)
    try:
        write_atomically(path, lambda stream: fig.savefig(stream, format=path.suffix[1:].lower(), dpi=110))
    finally:
        plt.close(fig)
    return path


def figure(runs: Sequence[tuple[Scenario, RunResult]]) -> Figure:
    """The figure of ``(scenario, result)`` pairs, overlaid (needs matplotlib).

    Panels (``ax.get_label()``): ``position`` and ``orientation`` error (the latter only if a
    run tracks the orientation), one speed panel per group of :func:`speed_groups` (``base``,
    ``wheels``, ``arm``; one run shows every joint, several the largest ratio of each run),
    ``latency``, ``paths`` (top view, start and end marked), when a scenario watches the
    manipulability, ``m``, and when a scenario has priority levels, ``posture`` (the error of
    each run's PostureTask, :func:`wbc.closed_loop.posture_traces`).
    """
    if not runs:
        raise ValueError("figure() needs at least one (scenario, result) pair")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    results = [result for _, result in runs]
    groups = [speed_groups(scenario.robot, result) for scenario, result in runs]
    trace = manipulability_traces(runs)
    postures = posture_traces(runs)
    error_keys = ["position"] + (["orientation"] if any(r.orientation_tracked for r in results) else [])
    speed_keys = [key for key in ("base", "wheels", "arm") if any(g.key == key for gs in groups for g in gs)]
    layout = [_row(error_keys), _row(speed_keys), _row(["latency", "paths"])] + ([_row(["m"])] if trace else [])
    layout += [_row(["posture"])] if postures else []
    fig, axes = plt.subplot_mosaic(layout, figsize=(13, 3.8 * len(layout)), constrained_layout=True)
    colors = [plt.rcParams["axes.prop_cycle"].by_key()["color"][k % 10] for k in range(len(runs))]
    several = len(runs) > 1

    frames = {scenario.reference_task.frame for scenario, _ in runs if scenario.reference_task is not None}
    of_frame = f" of '{next(iter(frames))}'" if len(frames) == 1 else ""
    with_reference = [(r, c) for r, c in zip(results, colors, strict=True) if r.tool_path is not None]
    _error_panel(axes["position"], f"Position error{of_frame}", "‖p* − p‖ [mm]",
                 [(r.time, r.position_error * 1e3, c, r.scenario) for r, c in with_reference], "mm")
    if "orientation" in axes:
        _error_panel(axes["orientation"], f"Orientation error{of_frame}", "‖log3(R* Rᵀ)‖ [mrad]",
                     [(r.time, r.orientation_error * 1e3, c, r.scenario) for r, c in with_reference
                      if r.orientation_tracked], "mrad")

    for key in speed_keys:
        ax = axes[key]
        top = 1.0
        for result, color, run_groups in zip(results, colors, groups, strict=True):
            group = next((g for g in run_groups if g.key == key), None)
            if group is None:
                continue
            ax.set(title=group.title, ylabel=group.ylabel)
            ratio = (result.wheel_ratio if key == "wheels" else result.velocity_ratio)[:, group.columns]
            top = max(top, float(ratio.max()))
            if several:
                ax.plot(result.time, ratio.max(axis=1), lw=1, color=color, label=f"{result.scenario}: max")
            else:
                for i, label in enumerate(group.labels):
                    ax.plot(result.time, ratio[:, i], lw=1, label=label)
        ax.axhline(1.0, color="k", ls="--", lw=1, label="limit")
        ax.set(xlabel="time [s]", ylim=(0, 1.15 * top))
        ax.legend(fontsize=7, ncol=2 if len(ax.get_legend_handles_labels()[1]) > 4 else 1)
        ax.grid(True, alpha=0.3)

    ax = axes["latency"]
    for result, color in zip(results, colors, strict=True):
        prefix, color = (f"{result.scenario}: ", color) if several else ("", None)
        ax.plot(result.time, result.tick_time * 1e6, lw=0.6, color=color, label=f"{prefix}tick (step)")
        ax.plot(result.time, result.solve_time * 1e6, lw=0.6, color=color, ls=":" if several else "-",
                label=f"{prefix}solve ({result.solver})")
    top = max(np.percentile(result.tick_time, 99.5) for result in results)
    ax.set(title="Latency", xlabel="time [s]", ylabel="time per tick [µs]", ylim=(0, top * 1.5e6))
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)

    _paths_panel(axes["paths"], results, colors)

    if trace is not None:
        ax = axes["m"]
        for result, series, color in zip(results, trace.series, colors, strict=True):
            if series is None:
                continue
            ax.plot(np.arange(series.size) * result.dt, series, color=color, label=result.scenario)
        if trace.min_value is not None:
            ax.axhline(trace.min_value, color="k", ls="--", lw=1, label=f"m_min = {trace.min_value:g}")
        ax.set(title=f"Manipulability m of '{trace.frame}' ({trace.rows} rows)", xlabel="time [s]", ylabel="m",
               ylim=(0, None))
        ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)

    if postures:
        ax = axes["posture"]
        for result, series, color in zip(results, postures, colors, strict=True):
            if series is not None:
                ax.plot(np.arange(series.size) * result.dt, series, color=color, label=result.scenario)
        ax.set(title="Posture error ‖q* ⊖ q‖ of the PostureTask", xlabel="time [s]", ylabel="[rad]", ylim=(0, None))
        ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)

    names = ", ".join(result.scenario for result in results)
    fig.suptitle(f"{names} — {results[0].solver}, dt = {results[0].dt * 1e3:.0f} ms")
    return fig


def _row(keys: list[str]) -> list[str]:
    """One row of the mosaic: ``keys`` side by side, equally wide."""
    return [key for key in keys for _ in range(GRID_COLUMNS // len(keys))]


def _error_panel(ax: Axes, title: str, ylabel: str, lines: list[tuple[np.ndarray, np.ndarray, str, str]],
                 unit: str) -> None:
    """Log-scale error lines (time, error, colour, scenario), the axis starting at :func:`log_floor`."""
    ax.set(title=title, xlabel="time [s]", ylabel=ylabel, yscale="log")
    ax.grid(True, which="both", alpha=0.3)
    floor = log_floor([error for _, error, _, _ in lines])
    if floor is None:
        ax.text(0.5, 0.5, "no tracking error recorded" if not lines else "zero error throughout",
                transform=ax.transAxes, ha="center", va="center")
        return
    for time, error, color, name in lines:
        ax.plot(time, np.maximum(error, floor), color=color, label=name)
    ax.set_ylim(bottom=floor)
    if any(np.min(error) < floor for _, error, _, _ in lines):
        ax.text(0.01, 0.02, f"errors below {floor:.0e} {unit} drawn at the axis", transform=ax.transAxes,
                fontsize=7, color="0.35", bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8})
    if len(lines) > 1:
        ax.legend(fontsize=7)


def _paths_panel(ax: Axes, results: Sequence[RunResult], colors: Sequence[str]) -> None:
    """Top view of the base and tool paths, each with its start (○) and end (■) marked."""
    several = len(results) > 1
    for result, color in zip(results, colors, strict=True):
        prefix = f"{result.scenario}: " if several else ""
        for path, part, style, own in ((result.base_path, "base", "-", "C0"), (result.tool_path, "tool", "--", "C1")):
            if path is None:
                continue
            line_color = color if several else own
            ax.plot(path[:, 0], path[:, 1], color=line_color, ls=style, label=f"{prefix}{part}")
            ax.plot(path[0, 0], path[0, 1], ls="none", marker="o", mfc="white", mec=line_color, ms=7, mew=1.5)
            ax.plot(path[-1, 0], path[-1, 1], ls="none", marker="s", color=line_color, ms=6)
    ax.plot([], [], ls="none", marker="o", mfc="white", mec="k", label="start")
    ax.plot([], [], ls="none", marker="s", color="k", label="end")
    ax.set(title="Paths (top view, world x-y)", xlabel="x [m]", ylabel="y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
