"""Perturbed starts: each scenario's closed loop recorded again from seeded perturbations of its
initial configuration (``wbc bench solvers --starts N``: the nominal start and N - 1 perturbed ones).

Start 0 is the scenario's own initial configuration ``q0``: the dataset of :mod:`benchmarks.dataset`.
Start ``s >= 1`` runs the same closed loop (same tasks, targets and reference, all built from ``q0``)
from ::

    q = clip(integrate(q0, d, 1 s), lower + MARGIN * range, upper - MARGIN * range)
    d_i ~ Uniform(-AMPLITUDE, AMPLITUDE) on every velocity coordinate (rad, or m for a base translation)

drawn from ``numpy.random.default_rng([seed, s, crc32(scenario name)])`` (``--start-seed``, default 0):
a start depends on the seed, its number and the scenario only, not on which other starts or
scenarios are swept. Coordinates without limits (a mobile base's pose) are not clipped. The
controller pulls the robot back onto the scenario's path within its first ticks: a few cm and degrees
off, the scenario keeps its meaning (the same limits become active, the same singular passes).

Stored next to the dataset, ``<dataset>/v<VERSION>/starts/<scenario>_s<start>.npz`` (the arrays of
:mod:`benchmarks.dataset`, plus its index entry as JSON under ``meta``), as many ticks as the nominal
recording. A file is recorded again when it no longer matches: another seed, a start that computes
differently now (model, amplitude), or a nominal dataset recorded since.
"""

from __future__ import annotations

import json
import tempfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import dataset as ds
from .common import TASKS
from .sweep import Mapper

#: half-width of the uniform perturbation of each velocity coordinate, integrated over 1 s [rad or m]
AMPLITUDE = 0.05
#: the perturbed start stays this share of each bounded coordinate's range inside its limits
MARGIN = 0.01


def perturbed_configuration(robot, q0: np.ndarray, scenario: str, start: int, seed: int) -> np.ndarray:
    """Perturbed start ``start`` (>= 1) of ``scenario`` from its initial configuration ``q0``."""
    if start < 1:
        raise ValueError(f"perturbed starts are numbered from 1 (0 is the scenario's own); got {start}")
    rng = np.random.default_rng([seed, start, zlib.crc32(scenario.encode())])
    q = robot.integrate(q0, rng.uniform(-AMPLITUDE, AMPLITUDE, robot.nv), 1.0)
    span = robot.upper - robot.lower
    bounded = np.isfinite(span)
    q[bounded] = np.clip(q[bounded], robot.lower[bounded] + MARGIN * span[bounded],
                         robot.upper[bounded] - MARGIN * span[bounded])
    return q


@dataclass(frozen=True)
class StartJob:
    """What a worker needs to record one perturbed start: the scenario file's text, no shared files."""

    scenario: str
    source: str  #: the scenario file's name (its stem names the scenario when the file does not)
    text: str
    start: int
    seed: int
    ticks: int
    dataset_created: str  #: the nominal dataset this start goes with (``index["created"]``)

    @property
    def label(self) -> str:
        return f"record {self.scenario} start {self.start}"


def record_start(job: StartJob) -> dict:
    """Record ``job`` (on a worker or here): ``{"entry", "arrays"}`` as :func:`dataset.record_scenario`."""
    from wbc.app.scenario import load_scenario

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / job.source
        path.write_text(job.text)
        scenario = load_scenario(path)
        q0 = perturbed_configuration(scenario.robot, scenario.q0, job.scenario, job.start, job.seed)
        result = ds.record_scenario(path, job.ticks * scenario.dt, show_progress=False, q0=q0)
    result["entry"].update(start=job.start, start_seed=job.seed, requested_ticks=job.ticks,
                           dataset_created=job.dataset_created, file=start_path(Path(), job.scenario, job.start).name)
    return result


def start_path(folder: Path, scenario: str, start: int) -> Path:
    """Where perturbed start ``start`` of ``scenario`` is stored in the dataset version folder ``folder``."""
    return folder / "starts" / f"{scenario}_s{start}.npz"


def _read(path: Path) -> tuple[dict, dict[str, np.ndarray]] | None:
    if not path.exists():
        return None
    with np.load(path) as data:
        arrays = {key: data[key] for key in data.files if key != "meta"}
        return json.loads(str(data["meta"])), arrays


def _jobs(folder: Path, index: dict, nominal: Sequence[ds.ScenarioQPs], starts: int, seed: int,
          tasks: Path) -> list[StartJob]:
    """The starts of ``nominal`` that are missing or stale in ``folder``."""
    from wbc.app.scenario import load_scenario

    jobs = []
    for sc in nominal:
        source = tasks / sc.meta["source"]
        if not source.exists():
            raise FileNotFoundError(f"perturbed starts of {sc.name}: its scenario file {source} is gone; "
                                    "record the dataset again (--regenerate) or sweep without --starts")
        scenario = None
        for start in range(1, starts):
            stored = _read(start_path(folder, sc.name, start))
            if stored is not None:
                meta, arrays = stored
                if scenario is None:
                    scenario = load_scenario(source)
                expected = perturbed_configuration(scenario.robot, scenario.q0, sc.name, start, seed)
                if (meta.get("start_seed") == seed and meta.get("requested_ticks") == sc.ticks
                        and meta.get("dataset_created") == index["created"]
                        and np.array_equal(arrays["q"][0], expected)):
                    continue
            jobs.append(StartJob(sc.name, source.name, source.read_text(), start, seed, sc.ticks, index["created"]))
    return jobs


def ensure_starts(folder: Path, index: dict, nominal: Sequence[ds.ScenarioQPs], starts: int, seed: int,
                  run: Mapper, tasks: Path = TASKS) -> int:
    """Record the perturbed starts 1 .. ``starts`` - 1 of ``nominal`` that ``folder`` (the dataset's
    version folder) lacks, through ``run`` (here or on workers); the number recorded."""
    jobs = _jobs(folder, index, nominal, starts, seed, tasks)
    if jobs:
        (folder / "starts").mkdir(exist_ok=True)
    for job, result in zip(jobs, run(record_start, jobs, [job.label for job in jobs]), strict=True):
        meta = json.dumps(result["entry"])
        np.savez_compressed(start_path(folder, job.scenario, job.start), meta=np.array(meta), **result["arrays"])
    return len(jobs)


def load_starts(folder: Path, nominal: Sequence[ds.ScenarioQPs], starts: int) -> list[ds.ScenarioQPs]:
    """Every scenario of ``nominal`` followed by its perturbed starts 1 .. ``starts`` - 1 (recorded by
    :func:`ensure_starts`)."""
    out = []
    for sc in nominal:
        out.append(sc)
        for start in range(1, starts):
            stored = _read(start_path(folder, sc.name, start))
            if stored is None:
                raise FileNotFoundError(f"perturbed start {start} of {sc.name} is not recorded in {folder}")
            meta, arrays = stored
            out.append(ds.scenario_qps(meta, arrays, start))
    return out
