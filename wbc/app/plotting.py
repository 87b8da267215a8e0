"""Figure of closed-loop runs: tracking errors, speeds against their limits (one panel per
role of the joints: mobile base, wheels, the chain to the tracked frame, the others), latency,
paths, and the manipulability m(t) when a scenario watches it. Several runs are overlaid, one
colour each.

Read for any robot: a speed panel draws at most :data:`MAX_LINES` joints, those closest to
their limits, named with their peak, and the largest ratio of the others as one grey line;
lines that coincide are drawn once under a joint name "FL = RR"; a panel whose joints barely
move says so instead of drawing flat lines; latencies above the axis are marked at its top
edge with their true maximum written next to them."""

from __future__ import annotations

import math
import re
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..model.robot import Robot
from .closed_loop import RunResult, collision_traces, manipulability_traces, posture_traces
from .outputs import check_output, write_atomically
from .scenario import Scenario

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from matplotlib.typing import HashableList

FLOOR_DECADES = 3  #: the error panels' log axes start this many decades below the median error
WHEEL_NAMES = {4: ["FL", "FR", "RL", "RR"], 2: ["left", "right"]}  #: wheel order of wbc.model.mobile_base
GRID_COLUMNS = 6  #: the figure's grid: 1, 2 or 3 panels per row (four speed panels: two rows)
MAX_LINES = 6  #: joints drawn by name in a speed panel (the closest to their limits)
NEGLIGIBLE = 0.01  #: a speed panel whose every ratio stays below this says "barely moves"
ZOOM_BELOW = 0.1  #: a speed panel whose ratios stay below this gets an axis up to its peak, not to the limit
COINCIDE = 0.01  #: lines closer than this fraction of the panel's height everywhere are drawn once
LEGEND_ROW = 0.065  #: height of a legend row, as a fraction of a panel's height
LEGEND_COLUMN_CHARS = 32  #: a legend has two columns only if no label is longer than this
AGG_CHUNK = 10_000  #: points per piece of a long line when drawn (2x10^6-tick circle: 360 MB peak, 461 MB unchunked)
PLOT_ROWS = 5000  #: points of a line at most: a longer run is drawn coarsened (RunResult.coarsened), as said
LATENCY_TOP = 2.0  #: the latency axis ends at this multiple of the largest p99 (exact, every tick)
RUN_LINE = "run"  #: gid of the lines that the figure's legend of several runs names by their colour
LINE_STYLES = ("-", "--", "-.", ":")  #: cycled with the colours: lines that cross stay apart
WHEEL_JOINT = re.compile(r"wheel|caster", re.IGNORECASE)  #: joint names taken for wheels
#: what :func:`plot_runs` writes, by suffix: matplotlib's formats but those that need more
#: than matplotlib and Pillow (.pgf needs LaTeX, .avif a Pillow built with AVIF)
PLOT_FORMATS = {".png": "PNG", ".pdf": "PDF", ".svg": "SVG", ".svgz": "SVG (gzip)", ".eps": "EPS", ".ps": "PostScript",
                ".jpg": "JPEG", ".jpeg": "JPEG", ".tif": "TIFF", ".tiff": "TIFF", ".webp": "WebP", ".gif": "GIF"}


@dataclass
class JointRoles:
    """The velocity coordinates of a robot by role: ``base`` (x, y, yaw of a mobile base),
    ``wheels`` (joints named like a wheel or caster), ``chain`` (the joints on the kinematic
    path from the root to ``frame``) and ``other`` (the rest: a hand, a head, a second arm)."""

    frame: str | None
    base: list[int]
    wheels: list[int]
    chain: list[int]
    other: list[int]
    labels: list[str]  #: of every velocity coordinate (joint name, with [i] for a multi-DOF joint)


def joint_roles(robot: Robot, frame: str | None) -> JointRoles:
    """:class:`JointRoles` of ``robot`` for the tracked ``frame`` (None: no chain, every joint
    but the base's and the wheels' is "other")."""
    model = robot.model
    base = list(robot.base.indices) if robot.base.is_mobile else []
    chain_joints: set[int] = set()
    if frame is not None:
        joint = model.frames[robot.frame_id(frame)].parentJoint
        while joint > 0:
            chain_joints.add(joint)
            joint = model.parents[joint]
    roles = JointRoles(frame, base, [], [], [], [""] * robot.nv)
    for joint in range(1, model.njoints):
        name, first, count = model.names[joint], model.joints[joint].idx_v, model.joints[joint].nv
        for offset in range(count):
            column = first + offset
            roles.labels[column] = name if count == 1 else f"{name}[{offset}]"
            if column in base:
                continue
            role = (roles.chain if joint in chain_joints else roles.wheels if WHEEL_JOINT.search(name)
                    else roles.other)
            role.append(column)
    return roles


@dataclass
class SpeedGroup:
    """The speeds of one run shown together in one panel, each against its limit."""

    key: str  #: "base", "wheels", "chain" or "other"
    title: str
    labels: list[str]
    ratio: NDArray[np.float64]  #: (rows, len(labels)) ``|speed| / limit``
    unlimited: list[str]  #: joints of the group without a speed limit (not drawn)


def speed_groups(robot: Robot, result: RunResult, frame: str | None = None) -> list[SpeedGroup]:
    """The speed panels of one run: the mobile base's twist (in the base frame), its wheels
    (their speed computed from the twist if the base declares a limit, and joints named like
    a wheel), the chain to ``frame`` and the other joints, each against its own limit."""
    roles = joint_roles(robot, frame)
    limited = np.isfinite(robot.velocity_limit)
    groups = []
    if roles.base:
        yaw = roles.labels[roles.base[2]]
        groups.append(SpeedGroup("base", "Base: |v| / limit (base frame)", ["v_x forward", "v_y left",
                                 f"ω ({yaw})"], result.velocity_ratio[:, roles.base], []))
    wheel_labels, wheel_ratios = [], []
    if result.wheel_ratio is not None:
        count = result.wheel_ratio.shape[1]
        wheel_labels += WHEEL_NAMES.get(count, [f"wheel {i + 1}" for i in range(count)])
        wheel_ratios.append(result.wheel_ratio)
    titles = {"wheels": "Wheels: |u| / limit", "chain": f"Chain to '{frame}': |v| / limit",
              "other": "Other joints: |v| / limit" if roles.chain else "Joints: |v| / limit"}
    for key, columns in (("wheels", roles.wheels), ("chain", roles.chain), ("other", roles.other)):
        drawn = [c for c in columns if limited[c]]
        labels = [roles.labels[c] for c in drawn]
        ratios = [result.velocity_ratio[:, drawn]]
        if key == "wheels":
            labels, ratios = wheel_labels + labels, wheel_ratios + ratios
        if labels or columns:
            groups.append(SpeedGroup(key, titles[key], labels, np.hstack(ratios),
                                     [roles.labels[c] for c in columns if not limited[c]]))
    return groups


def log_floor(series: Sequence[ArrayLike], decades: int = FLOOR_DECADES) -> float | None:
    """Lower limit of a log axis for ``series``: a power of ten ``decades`` below the median of
    their positive values, or the smallest of them if that is higher; None if none is positive.
    Values below it are drawn on it, so an exact 0 or a 1e-12 does not stretch the axis."""
    values = np.concatenate([np.ravel(s) for s in series]) if series else np.zeros(0)
    positive = values[np.isfinite(values) & (values > 0)]
    if positive.size == 0:
        return None
    exponent = max(np.floor(np.log10(np.median(positive))) - decades, np.floor(np.log10(positive.min())))
    return float(10.0 ** exponent)


def plot_runs(runs: Sequence[tuple[Scenario, RunResult]], path: str | Path) -> Path:
    """Write the :func:`figure` of ``runs`` to ``path`` in the format its suffix names (one of
    :data:`PLOT_FORMATS`: .png, .pdf, .svg, ...), atomically: a temporary file in the same
    folder, renamed to ``path`` once complete; a missing folder is created (needs matplotlib:
    ``pip install wbc[plot]``).

    Args:
        runs: ``(scenario, result)`` pairs (:func:`wbc.app.closed_loop.run`), overlaid.
        path: the file to write.

    Returns:
        ``path``, as a :class:`~pathlib.Path`.

    Raises:
        OutputError: ``path`` cannot be written (:func:`wbc.app.outputs.check_output`); raised
            before the figure is drawn.
        OSError: writing failed (e.g. the disk is full); ``path`` is left as it was.
        ValueError: ``runs`` is empty.
    """
    import matplotlib
    import matplotlib.pyplot as plt

    path = check_output(str(path), PLOT_FORMATS)
    fig = figure(runs)
    try:
        # long lines (a long run's paths) drawn in pieces: Agg's memory grows with a path's drawn length
        with matplotlib.rc_context({"agg.path.chunksize": AGG_CHUNK}):
            write_atomically(path, lambda stream: fig.savefig(stream, format=path.suffix[1:].lower(), dpi=110))
    finally:
        plt.close(fig)
    return path


def figure(runs: Sequence[tuple[Scenario, RunResult]]) -> Figure:
    """The figure of ``(scenario, result)`` pairs, overlaid (needs matplotlib).

    Panels (``ax.get_label()``): ``position`` and ``orientation`` error (the latter only if a
    run tracks the orientation), one speed panel per group of :func:`speed_groups` (``base``,
    ``wheels``, ``chain``, ``other``; one run shows the joints closest to their limits, several
    the largest ratio of each run), ``latency``, ``paths`` (top view of a mobile base and its
    tool; for fixed bases the tool in the world plane of its largest extent; start and end
    marked), when a scenario watches the manipulability, ``m``, when a scenario has collision
    avoidance, ``distance`` (the smallest distance between its pairs per recorded tick against
    its min_distance, :func:`wbc.app.closed_loop.collision_traces`), and when a scenario has
    priority levels, ``posture`` (the error of each run's PostureTask,
    :func:`wbc.app.closed_loop.posture_traces`).
    """
    if not runs:
        raise ValueError("figure() needs at least one (scenario, result) pair")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    recorded = runs  # the paths are drawn from every recorded row: coarser, a periodic path would alias
    runs = [(scenario, result.coarsened(PLOT_ROWS)) for scenario, result in runs]
    results = [result for _, result in runs]
    groups = [speed_groups(scenario.robot, result, _tracked_frame(scenario)) for scenario, result in runs]
    trace = manipulability_traces(runs)
    distances = collision_traces(runs)
    postures = posture_traces(runs)
    error_keys = ["position"] + (["orientation"] if any(r.orientation_tracked for r in results) else [])
    speed_keys = [key for key in ("base", "wheels", "chain", "other") if any(g.key == key for gs in groups for g in gs)]
    speed_rows = [speed_keys] if len(speed_keys) < 4 else [speed_keys[:2], speed_keys[2:]]
    layout: list[HashableList[str]] = [_row(error_keys), *map(_row, speed_rows), _row(["latency", "paths"])]
    layout += [_row([key]) for key, shown in (("m", trace), ("distance", distances), ("posture", postures)) if shown]
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
        in_panel = [(result, color, group) for result, color, run_groups in zip(results, colors, groups, strict=True)
                    for group in run_groups if group.key == key]
        _speed_panel(axes[key], in_panel, several)

    if any(result.stride > 1 for result in results):
        _long_latency_panel(axes["latency"], results, colors)
    else:
        _latency_panel(axes["latency"], results, colors)
    _paths_panel(axes["paths"], [result for _, result in recorded], colors)

    if trace is not None:
        floor = None if trace.min_value is None else (trace.min_value, f"m_min = {trace.min_value:g}")
        _trace_panel(axes["m"], results, trace.series, colors, several, floor,
                     f"Manipulability m of '{trace.frame}' ({trace.rows} rows)", "m")
    if distances is not None:
        _trace_panel(axes["distance"], results, [None if d is None else d * 1e3 for d in distances.series], colors,
                     several, (distances.margin * 1e3, f"min_distance = {distances.margin * 1e3:g} mm"),
                     f"Smallest distance between collision pairs (within {distances.detection_distance:g} m)",
                     "[mm]")
    if postures:
        _trace_panel(axes["posture"], results, postures, colors, several, None,
                     "Posture error ‖q* ⊖ q‖ of the PostureTask", "[rad]")

    fig.suptitle(_suptitle(results))
    if several:  # the runs' colours, once for every panel
        fig.legend([Line2D([], [], color=color, lw=2) for color in colors], [r.scenario for r in results],
                   loc="outside lower center", ncol=min(len(results), 5), fontsize=9, frameon=False)
    return fig


def _trace_panel(ax: Axes, results: Sequence[RunResult], series: Sequence[NDArray[np.float64] | None],
                 colors: Sequence[str], several: bool, floor: tuple[float, str] | None, title: str,
                 ylabel: str) -> None:
    """One value per recorded configuration of each run (None: a run without it; inf is not
    drawn), and a dashed floor line with its label."""
    for result, values, color in zip(results, series, colors, strict=True):
        if values is not None:
            shown = np.where(np.isfinite(values), values, np.nan)
            ax.plot(np.arange(values.size) * result.dt * result.stride, shown, color=color, label=result.scenario,
                    gid=RUN_LINE)
    if floor is not None:
        ax.axhline(floor[0], color="k", ls="--", lw=1, label=floor[1])
    ax.set(title=title, xlabel="time [s]", ylabel=ylabel, ylim=(0, None))
    _legend(ax, several)
    ax.grid(True, alpha=0.3)

def _legend(ax: Axes, several: bool) -> None:
    """The legend of a panel: with several runs, only what is not a run (their colours are in
    the figure's legend), and none if that is nothing."""
    handles, labels = ax.get_legend_handles_labels()
    if several:
        runs = {line.get_label() for line in ax.get_lines() if line.get_gid() == RUN_LINE}
        handles, labels = [h for h, lab in zip(handles, labels, strict=True) if lab not in runs], \
            [lab for lab in labels if lab not in runs]
    if handles:
        ax.legend(handles, labels, fontsize=7)


def _tracked_frame(scenario: Scenario) -> str | None:
    """The frame whose chain a speed panel shows: the reference task's, else the robot's end effector."""
    task = scenario.reference_task
    return task.frame if task is not None else scenario.robot.end_effector


def _suptitle(results: Sequence[RunResult]) -> str:
    """The runs, their solvers, periods and loops (kinematic or MuJoCo), and what a long run kept."""
    def common(values: list[str]) -> str:
        return values[0] if len(set(values)) == 1 else " / ".join(values)

    loops = common([f"MuJoCo loop ({r.loop_details})" if r.loop == "mujoco" else "kinematic loop" for r in results])
    names = f"{results[0].scenario} — " if len(results) == 1 else ""
    lines = [f"{names}{common([r.solver for r in results])}, dt = {common([f'{r.dt * 1e3:g} ms' for r in results])}, "
             f"{loops}"]
    kept: dict[tuple[int, int], list[str]] = {}
    for r in results:
        if r.stride > 1:
            kept.setdefault((r.stride, r.ticks), []).append(r.scenario)
    lines += [f"{', '.join(names)}: every {_ordinal(stride)} of {ticks:,} ticks drawn, each point the largest "
              f"value of its {stride} ticks; the summary's numbers are over every tick"
              for (stride, ticks), names in kept.items()]
    return "\n".join(lines)


def _ordinal(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


#: a line of a speed panel: label, time [s], values, colour (None: the cycle's)
Line = tuple[str, NDArray[np.float64], NDArray[np.float64], "str | None"]


def _speed_panel(ax: Axes, in_panel: Sequence[tuple[RunResult, str, SpeedGroup]], several: bool) -> None:
    """Speeds against their limits: one run's joints closest to their limits (at most
    :data:`MAX_LINES`, named with their peak) and the largest ratio of the others; several
    runs: the largest ratio of each. A panel whose joints barely move says so instead."""
    frames = {group.title for _, _, group in in_panel}
    title = in_panel[0][2].title if len(frames) == 1 else f"{in_panel[0][2].key.capitalize()}: |v| / limit"
    title += " (largest of each run)" if several else ""
    ax.set(title=title, xlabel="time [s]", ylabel="speed / limit")
    ax.set_xlim(0.0, max(max(float(r.time[-1]), r.dt) for r, _, _ in in_panel))
    ax.grid(True, alpha=0.3)
    lines: list[Line] = []
    rest: list[Line] = []
    peak, peak_name, names = 0.0, "", []
    for result, color, group in in_panel:
        names += [f"{result.scenario}: {label}" if several else label for label in group.labels]
        if not group.labels:
            continue
        peaks = group.ratio.max(axis=0)
        strongest = int(np.argmax(peaks))
        if peaks[strongest] >= peak:
            peak, peak_name = float(peaks[strongest]), group.labels[strongest]
        if several:
            lines.append((result.scenario, result.time, group.ratio.max(axis=1), color))
            continue
        order = np.argsort(-np.round(peaks, 3), kind="stable")  # equal peaks in the model's order
        lines += [(group.labels[i], result.time, group.ratio[:, i], None) for i in order[:MAX_LINES]]
        if order.size > MAX_LINES:
            others = order[MAX_LINES:]
            rest.append((f"{others.size} others: max", result.time, group.ratio[:, others].max(axis=1), "0.6"))
    unlimited = sorted({name for _, _, group in in_panel for name in group.unlimited})
    if unlimited:
        ax.text(0.01, 0.02, f"no speed limit, not drawn: {_families(unlimited)}", transform=ax.transAxes, fontsize=7,
                color="0.35")
    if peak < NEGLIGIBLE:
        ax.axhline(1.0, color="k", ls="--", lw=1, label="limit")
        ax.set_ylim(0.0, 1.15)
        runs = f"{', '.join(r.scenario for r, _, _ in in_panel)}:\n" if several else ""
        ax.text(0.5, 0.5, runs + _still(names, peak, peak_name), transform=ax.transAxes, ha="center", va="center",
                fontsize=9, bbox={"facecolor": "white", "edgecolor": "0.6", "alpha": 0.9})
        return
    # small motions get an axis of their own, the limit above it (said in the legend)
    scale = peak if peak < ZOOM_BELOW else max(1.0, peak)
    label_order = [label for label, _, _, _ in lines] if several else in_panel[0][2].labels
    merged = _merge_coinciding(lines, COINCIDE * 1.15 * scale, label_order)
    drawn = [ax.plot(time, ratio, lw=1.2, color=color, ls=LINE_STYLES[n % len(LINE_STYLES)],
                     label=f"{label}  (peak {_ratio(ratio.max())})")[0]
             for n, (label, time, ratio, color) in enumerate(merged)]
    drawn += [ax.plot(time, ratio, lw=0.8, color=color, label=f"{label}  (peak {_ratio(ratio.max())})", zorder=1)[0]
              for label, time, ratio, color in rest]
    drawn.append(ax.axhline(1.0, color="k", ls="--", lw=1, label="limit" if scale >= 1.0 else
                            f"limit 1.0: above the axis (below {ZOOM_BELOW:.0%} of it throughout)"))
    labels = [str(line.get_label()) for line in drawn]
    columns = 2 if len(drawn) > 3 and max(map(len, labels)) <= LEGEND_COLUMN_CHARS else 1
    texts = [textwrap.fill(label, 2 * LEGEND_COLUMN_CHARS, break_on_hyphens=False) for label in labels]
    rows = -(-sum(text.count("\n") + 1 for text in texts) // columns)
    # the legend gets a band of its own above the data: it covers no line
    ax.set_ylim(0.0, scale * 1.04 / (1.0 - LEGEND_ROW * rows - 0.05))
    ax.legend(drawn, texts, fontsize=7, ncol=columns, loc="upper right", framealpha=0.9)


def _still(names: Sequence[str], peak: float, strongest: str) -> str:
    """What a speed panel says whose joints ``names`` stay below :data:`NEGLIGIBLE` of their
    limits (``peak``: the largest ratio, of joint ``strongest``)."""
    if not names:
        return "no joint with a speed limit"
    joints = names[0] if len(names) == 1 else f"{len(names)} joints ({_families(names)})"
    if peak == 0.0:
        return f"{joints}:\nno motion"
    limits = "their speed limits" if len(names) > 1 else "its speed limit"
    largest = f"\n(largest: {strongest}, {peak:.2%} of its limit)" if len(names) > 1 else f" (peak {peak:.2%})"
    return f"barely moves: {joints}\nbelow {NEGLIGIBLE:.0%} of {limits}{largest}"


def _families(names: Sequence[str]) -> str:
    """Joint names in short: both of two, else counted by their first word ("36 hand_…, 2 head_…")."""
    if len(names) <= 2:
        return ", ".join(names)
    counts: dict[str, int] = {}
    for name in names:
        family = name.split(": ")[-1].split("_")[0]
        counts[family] = counts.get(family, 0) + 1
    if len(counts) == 1:
        return f"{next(iter(counts))}_…"
    return ", ".join(f"{count} {family}_…" for family, count in counts.items())


def _ratio(value: float) -> str:
    """A speed ratio in a legend: two decimals, or two significant digits below 0.1."""
    return f"{value:.2f}" if value >= 0.1 or value == 0.0 else f"{value:.2g}"


def _merge_coinciding(lines: list[Line], tolerance: float, order: Sequence[str]) -> list[Line]:
    """``lines`` with those that stay within ``tolerance`` of an earlier one (same times) drawn
    once, at the larger of the two, labelled "first = second" in the order of ``order``."""
    merged: list[tuple[list[str], NDArray[np.float64], NDArray[np.float64], str | None]] = []
    for label, time, ratio, color in lines:
        for k, (kept_labels, kept_time, kept_ratio, kept_color) in enumerate(merged):
            if (kept_time.shape == time.shape and np.array_equal(kept_time, time)
                    and np.max(np.abs(kept_ratio - ratio)) < tolerance):
                merged[k] = (kept_labels + [label], kept_time, np.maximum(kept_ratio, ratio), kept_color)
                break
        else:
            merged.append(([label], time, ratio, color))
    return [(" = ".join(sorted(labels, key=order.index)), time, ratio, color) for labels, time, ratio, color in merged]


def _latency_panel(ax: Axes, results: Sequence[RunResult], colors: Sequence[str]) -> None:
    """Tick and solve time per tick, on an axis up to :data:`LATENCY_TOP` times the largest p99
    (a spike of the machine does not squash the rest); points above it are marked ▲ at the top
    edge, and the legend writes out the largest of them. Several runs: one legend entry each
    (tick solid, solve dotted)."""
    several = len(results) > 1
    top = LATENCY_TOP * max(r.statistics.tick_latency_p99 for r in results) * 1e6
    clipped: list[tuple[float, float, str]] = []  # (value [µs], time [s], what)
    for result, color in zip(results, colors, strict=True):
        stats = result.statistics
        tick, solve = stats.tick_latency_median * 1e6, stats.solve_time_median * 1e6
        labels: tuple[str, str | None]
        if several:
            labels = (f"{result.scenario}: {tick:.1f} / {solve:.1f} µs", None)
        else:
            labels = (f"tick (step), median {tick:.1f} µs", f"solve ({result.solver}), median {solve:.1f} µs")
        for values, what, style, label in ((result.tick_time, "tick", "-", labels[0]),
                                           (result.solve_time, "solve", ":" if several else "-", labels[1])):
            us = values * 1e6
            (line,) = ax.plot(result.time, us, lw=0.6, color=color if several else None, ls=style, label=label)
            above = us > top
            if np.any(above):
                ax.plot(result.time[above], np.full(int(above.sum()), top), ls="none", marker="^", ms=5,
                        color=line.get_color(), clip_on=False)
                worst = int(np.argmax(us))
                clipped.append((float(us[worst]), float(result.time[worst]),
                                f"{result.scenario}: {what}" if several else what))
    if several:
        ax.plot([], [], color="k", lw=0.8, label="medians: tick (step) / solve (dotted)")
    ax.set(title="Latency", xlabel="time [s]", ylabel="time per tick [µs]", ylim=(0, top))
    if clipped:
        value, time, what = max(clipped)
        ax.plot([], [], ls="none", marker="^", ms=5, color="k",
                label=f"above the axis: largest {value:,.0f} µs ({what}, t = {time:.2f} s)")
    ax.legend(fontsize=7, loc="upper left", framealpha=0.9, ncol=2 if len(results) > 4 else 1)
    ax.grid(True, alpha=0.3)


def _long_latency_panel(ax: Axes, results: Sequence[RunResult], colors: Sequence[str]) -> None:
    """The latency of runs recorded one row per several ticks: the largest tick time of each
    row, on a log axis that holds them all, and the median and p99 over every tick as lines."""
    several = len(results) > 1
    low, high = math.inf, 0.0
    for result, color in zip(results, colors, strict=True):
        stats, prefix = result.statistics, f"{result.scenario}: " if several else ""
        (line,) = ax.plot(result.time, result.tick_time * 1e6, lw=0.6, color=color if several else None,
                          label=f"{prefix}largest tick time of each {result.stride}")
        median, p99 = stats.tick_latency_median * 1e6, stats.tick_latency_p99 * 1e6
        ax.axhline(median, color=line.get_color(), ls="--", lw=1,
                   label=f"{prefix}median {median:.1f} µs (solve {stats.solve_time_median * 1e6:.1f} µs)")
        ax.axhline(p99, color=line.get_color(), ls=":", lw=1, label=f"{prefix}p99 {p99:.1f} µs")
        low, high = min(low, median), max(high, float(result.tick_time.max()) * 1e6)
    ax.set(title="Latency (every tick: median and p99; log scale)", xlabel="time [s]", ylabel="time per tick [µs]",
           yscale="log", ylim=(low / 2, high * 3))
    ax.legend(fontsize=7, loc="upper left", framealpha=0.9, ncol=2 if several else 1)
    ax.grid(True, which="both", alpha=0.3)


def _row(keys: list[str]) -> HashableList[str]:
    """One row of the mosaic: ``keys`` side by side, equally wide."""
    return [key for key in keys for _ in range(GRID_COLUMNS // len(keys))]


def _error_panel(ax: Axes, title: str, ylabel: str,
                 lines: list[tuple[NDArray[np.float64], NDArray[np.float64], str, str]], unit: str) -> None:
    """Log-scale error lines (time, error, colour, scenario), the axis starting at :func:`log_floor`."""
    ax.set(title=title, xlabel="time [s]", ylabel=ylabel, yscale="log")
    ax.grid(True, which="both", alpha=0.3)
    floor = log_floor([error for _, error, _, _ in lines])
    if floor is None:
        ax.text(0.5, 0.5, "no tracking error recorded" if not lines else "zero error throughout",
                transform=ax.transAxes, ha="center", va="center")
        return
    for time, error, color, name in lines:
        ax.plot(time, np.maximum(error, floor), color=color, label=name, gid=RUN_LINE)
    top = max(float(np.max(error)) for _, error, _, _ in lines)
    ax.set_ylim(floor, top * (top / floor) ** 0.05 if top > floor else 10 * floor)  # a line at its top stays seen
    if any(np.min(error) < floor for _, error, _, _ in lines):
        ax.text(0.01, 0.02, f"errors below {floor:.0e} {unit} drawn at the axis", transform=ax.transAxes,
                fontsize=7, color="0.35", bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8})


def _paths_panel(ax: Axes, results: Sequence[RunResult], colors: Sequence[str]) -> None:
    """The base and tool paths seen from above (any run with a mobile base), or else the tool
    paths in the world plane of their two largest extents; each with its start (○) and end (■)."""
    several = len(results) > 1
    plane = _path_plane(results)
    for result, color in zip(results, colors, strict=True):
        prefix = f"{result.scenario}: " if several else ""
        tool = None if result.tool_path is None else result.tool_path[:, plane]
        for path, part, style, own in ((result.base_path, "base", "-", "C0"), (tool, "tool", "--", "C1")):
            if path is None:
                continue
            line_color = color if several else own
            ax.plot(path[:, 0], path[:, 1], color=line_color, ls=style, label=f"{prefix}{part}",
                    gid=RUN_LINE if several else None)
            ax.plot(path[0, 0], path[0, 1], ls="none", marker="o", mfc="white", mec=line_color, ms=7, mew=1.5)
            ax.plot(path[-1, 0], path[-1, 1], ls="none", marker="s", color=line_color, ms=6)
    if several:
        for part, style in (("base", "-"), ("tool", "--")):
            if any(getattr(r, f"{part}_path") is not None for r in results):
                ax.plot([], [], color="k", ls=style, label=part)
    ax.plot([], [], ls="none", marker="o", mfc="white", mec="k", label="start")
    ax.plot([], [], ls="none", marker="s", color="k", label="end")
    first, second = ("xyz"[i] for i in plane)
    view = "top view" if plane == [0, 1] and any(r.base_path is not None for r in results) else "tool"
    ax.set(title=f"Paths ({view}, world {first}-{second})", xlabel=f"{first} [m]", ylabel=f"{second} [m]")
    ax.set_aspect("equal", adjustable="datalim")
    _legend(ax, several)
    ax.grid(True, alpha=0.3)


def _path_plane(results: Sequence[RunResult]) -> list[int]:
    """World axes of the paths panel: x-y when a base moves on the floor, else the two axes
    along which the tool paths extend most (in x, y, z order)."""
    tools = [r.tool_path for r in results if r.tool_path is not None]
    if any(r.base_path is not None for r in results) or not tools:
        return [0, 1]
    points = np.vstack(tools)
    extent = points.max(axis=0) - points.min(axis=0)
    return sorted(int(i) for i in np.argsort(-extent, kind="stable")[:2])
