"""Helpers shared by the benchmark suites: paths, machine notes, timing statistics, tables."""

from __future__ import annotations

import datetime as _dt
import os
import platform
import subprocess
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TASKS = ROOT / "tasks"
MODELS = ROOT / "models"
#: generated reports and data go below this folder (git-ignored)
OUTPUT = ROOT / "benchmarks" / "output"


def scenario_files(folder: Path = TASKS) -> list[Path]:
    """Every scenario file ``*.toml`` in ``folder``, sorted by name."""
    return sorted(Path(folder).glob("*.toml"))


def git_commit(root: Path = ROOT) -> str:
    """Short commit of the checkout (+ ``-dirty`` with local changes), or ``"unknown"``."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True,
                                text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, check=True).stdout.strip()
        return commit + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def cpu_name() -> str:
    """CPU model from /proc/cpuinfo (Linux) or ``platform.processor()``."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def package_versions(names: Iterable[str]) -> dict[str, str]:
    """Installed versions of distributions (``"-"`` when missing)."""
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for name in names:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "-"
    return out


def machine_note() -> str:
    """One line describing where and when numbers were measured."""
    now = _dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    return (f"{now}; {cpu_name()}, {os.cpu_count()} logical cores; Python {platform.python_version()}; "
            f"{platform.system()} {platform.release()}; wbc commit {git_commit()}")


def percentiles_us(values: Sequence[float]) -> dict[str, float]:
    """min / median / p90 / p99 / max of durations given in seconds, returned in µs."""
    array = np.asarray(values, dtype=np.float64) * 1e6
    return {"min": float(array.min()), "median": float(np.median(array)),
            "p90": float(np.percentile(array, 90)), "p99": float(np.percentile(array, 99)),
            "max": float(array.max()), "n": int(array.size)}


def shifted_geometric_mean(values: Sequence[float], shift: float = 10.0) -> float:
    """``exp(mean(log(v + shift))) - shift`` of nonnegative values (qpbenchmark's aggregate)."""
    array = np.asarray(values, dtype=np.float64)
    if array.size == 0:
        return float("nan")
    if np.any(array < 0):
        raise ValueError("shifted geometric mean of negative values")
    return float(np.exp(np.mean(np.log(array + shift))) - shift)


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[object]], align: str | None = None) -> str:
    """A GitHub markdown table; ``align`` is one character per column (``l`` or ``r``)."""
    align = align or "l" + "r" * (len(header) - 1)
    lines = ["| " + " | ".join(header) + " |",
             "|" + "|".join(":---" if a == "l" else "---:" for a in align) + "|"]
    for row in rows:
        lines.append("| " + " | ".join(str(cell) for cell in row) + " |")
    return "\n".join(lines)


def fmt(value: float, digits: int = 1) -> str:
    """Fixed-point for ordinary numbers, scientific for tiny or huge ones, ``-`` for NaN."""
    if value is None or not np.isfinite(value):
        return "-" if value is None or np.isnan(value) else ("inf" if value > 0 else "-inf")
    if value != 0 and (abs(value) < 10 ** -digits or abs(value) >= 1e6):
        return f"{value:.1e}"
    return f"{value:.{digits}f}"


def progress(iterable, **kwargs):
    """tqdm progress bar on stderr (a plain iterator when ``disable=True``)."""
    from tqdm import tqdm

    kwargs.setdefault("mininterval", 0.5)
    kwargs.setdefault("file", sys.stderr)
    kwargs.setdefault("dynamic_ncols", True)
    return tqdm(iterable, **kwargs)
