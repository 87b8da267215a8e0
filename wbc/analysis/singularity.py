"""Singularities: certified analytic conditions and numeric rank tools (docs/singularities.md).

All numeric tools work on the frame Jacobian the controller uses: 6 x n, world-aligned
axes at the frame origin, rows (linear [m/s]; angular [rad/s]) -- see :mod:`wbc.model.robot` --
restricted to the columns of the moving joints. Rank does not depend on that choice of
axes or reference point on the same body: changing them multiplies J by an invertible
6 x 6 adjoint.

Linear and angular rows have different units, so singular values and determinants of J
depend on the length unit. wbc therefore works with the dimensionless

    J_s = diag(I3 / L, I3) J diag(c),   c_j = L for translational joints, 1 for revolute,

where L [m] is the system's ``length_scale`` (registered per model, or passed in). J_s is
what a metre -> millimetre change leaves invariant once L is expressed in the same unit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..core.validation import as_positive
from ..model.robot import Robot
from .scorbot_angles import scorbot_dh_angles, scorbot_measured_angles
from .singular_sets import SingularCondition, SingularSystem, registered_models, singular_systems

RESIDUAL_TOLERANCE = 1e-9  # |residual| <= this counts as on a set (residuals are dimensionless)
RANK_TOLERANCE = 1e-10  # singular values of J_s below this times the largest one count as zero


def singular_system(robot: Robot, subsystem: str | None = None) -> SingularSystem:
    """The registered system ``subsystem`` of ``robot`` (default: its first, e.g. the whole body)."""
    systems = singular_systems(robot)
    if subsystem is None:
        return systems[0]
    for system in systems:
        if system.name == subsystem:
            return system
    raise InvalidInputError(f"robot {robot.name!r} has no subsystem {subsystem!r}; "
                            f"known: {[s.name for s in systems]}")


def analytic_conditions(robot: Robot, subsystem: str | None = None) -> tuple[SingularCondition, ...]:
    """The certified singular conditions: the singular set is the union of their zero sets."""
    return singular_system(robot, subsystem).conditions


def is_singular(robot: Robot, q: ArrayLike, tol: float = RESIDUAL_TOLERANCE, subsystem: str | None = None) -> bool:
    """True where some condition holds: ``max_i |residual_i(q)| <= tol`` (residuals are dimensionless)."""
    q = robot.check_configuration(q)
    tol = as_positive(tol, "tol")
    return any(c.residual(q) <= tol for c in analytic_conditions(robot, subsystem))


def _setup(robot: Robot, frame: str | None, subsystem: str | None,
           length_scale: float | None) -> tuple[str, list[int], float | None]:
    """Frame, columns and length scale: the registered system's, overridden by explicit arguments."""
    if robot.name in registered_models():
        system = singular_system(robot, subsystem)
        frame = system.frame if frame is None else frame
        columns, scale = list(system.columns), system.length_scale
    else:
        if subsystem is not None:
            raise InvalidInputError(f"robot {robot.name!r} has no registered subsystems")
        frame = robot.end_effector if frame is None else frame
        if frame is None:
            raise InvalidInputError(f"robot {robot.name!r} declares no end effector: pass frame=")
        columns, scale = list(range(robot.nv)), None
    if length_scale is not None:
        scale = as_positive(length_scale, "length_scale")
    return frame, columns, scale


def scaled_jacobian(robot: Robot, q: ArrayLike, frame: str | None = None, subsystem: str | None = None,
                    length_scale: float | None = None) -> NDArray[np.float64]:
    """J_s = diag(I/L, I) J diag(c) (see the module docstring); L = 1 m if none is known."""
    frame, columns, scale = _setup(robot, frame, subsystem, length_scale)
    scale = 1.0 if scale is None else scale
    rows, over_inputs = _rows_and_inputs(robot, subsystem)
    jacobian = robot.frame_jacobian(q, frame)
    if over_inputs:
        jacobian = jacobian @ robot.input_map(robot.check_configuration(q))
    jacobian = jacobian[:, columns]
    translational = np.all(jacobian[3:] == 0.0, axis=0) & np.any(jacobian[:3] != 0.0, axis=0)
    jacobian[:3] /= scale
    jacobian[:, translational] *= scale
    return jacobian[list(rows)]


def _rows_and_inputs(robot: Robot, subsystem: str | None) -> tuple[tuple[int, ...], bool]:
    """Task rows and input form of the registered system (all rows over v otherwise)."""
    if robot.name in registered_models():
        system = singular_system(robot, subsystem)
        return system.rows, system.over_inputs
    return tuple(range(6)), False


def numeric_rank(robot: Robot, q: ArrayLike, frame: str | None = None, tol: float = RANK_TOLERANCE,
                 subsystem: str | None = None) -> int:
    """Number of singular values of J_s above ``tol * sigma_max``."""
    tol = as_positive(tol, "tol")
    sigma = np.linalg.svd(scaled_jacobian(robot, q, frame, subsystem), compute_uv=False)
    return int(np.sum(sigma > tol * sigma[0])) if sigma[0] > 0.0 else 0


def lost_directions(robot: Robot, q: ArrayLike, frame: str | None = None, tol: float = RANK_TOLERANCE,
                    subsystem: str | None = None) -> NDArray[np.float64]:
    """Left null space of J: a 6 x k matrix W with orthonormal columns and W^T J = 0
    (len(rows) x k for a system on some rows only, e.g. 3 x k for De Luca's wrist centre).

    Every achievable twist t = J v (linear; angular, world-aligned at the frame origin)
    satisfies W^T t = 0; read as wrenches (force; moment), the columns of W are loads the
    structure carries with zero joint torque. k = 6 - rank (a 5-DOF arm always has k >= 1).
    """
    tol = as_positive(tol, "tol")
    frame, columns, scale = _setup(robot, frame, subsystem, None)
    scaled = scaled_jacobian(robot, q, frame, subsystem)
    u, sigma, _ = np.linalg.svd(scaled)
    rank = int(np.sum(sigma > tol * sigma[0])) if sigma[0] > 0.0 else 0
    # W_s^T D J C = 0 with D = diag(I/L, I)  =>  (D W_s)^T J = 0
    rows, _ = _rows_and_inputs(robot, subsystem)
    unscale = np.r_[np.full(3, 1.0 / (1.0 if scale is None else scale)), np.ones(3)][list(rows)]
    basis, _ = np.linalg.qr(unscale[:, None] * u[:, rank:])
    return basis


def singularity_measure(robot: Robot, q: ArrayLike, frame: str | None = None, subsystem: str | None = None,
                        length_scale: float | None = None) -> float:
    """det(J_s^T J_s) for tall or square J_s, det(J_s J_s^T) for wide J_s = prod_i sigma_i(J_s)^2.

    Dimensionless; sqrt of it is Yoshikawa's manipulability of J_s. For an unregistered
    robot ``length_scale`` [m] must be given.
    """
    _, _, scale = _setup(robot, frame, subsystem, length_scale)
    if scale is None:
        raise InvalidInputError(f"robot {robot.name!r} has no registered length scale: pass length_scale=")
    sigma = np.linalg.svd(scaled_jacobian(robot, q, frame, subsystem, scale), compute_uv=False)
    return float(np.prod(sigma**2))


def in_singular_region(robot: Robot, q: ArrayLike, threshold: float, frame: str | None = None,
                       subsystem: str | None = None, length_scale: float | None = None) -> bool:
    """The singular region of Lu et al.: ``singularity_measure(q) <= threshold``.

    ``threshold`` is dimensionless: with L fixed, measure = prod sigma_i^2, so a threshold
    m0 / k^2 flags the configurations where one scaled singular value has fallen k times
    below its value in a reference configuration of measure m0 (others unchanged).
    """
    threshold = as_positive(threshold, "threshold")
    return singularity_measure(robot, q, frame, subsystem, length_scale) <= threshold


@dataclass
class Agreement:
    """Counts of samples where the numeric rank and the analytic conditions agree."""

    label: str
    agree: int = 0
    total: int = 0
    failures: list[NDArray[np.float64]] = field(default_factory=list)

    def add(self, ok: bool, q: NDArray[np.float64]) -> None:
        self.total += 1
        self.agree += ok
        if not ok:
            self.failures.append(q)


def _step_off(robot: Robot, condition: SingularCondition, q: NDArray[np.float64], epsilon: float,
              rng: np.random.Generator) -> NDArray[np.float64]:
    """q moved by epsilon in a random direction that leaves the set (residual >= epsilon / 10;
    after 100 failed draws the last one is returned and the check reports what it finds)."""
    for _ in range(100):
        step = rng.normal(size=q.size)
        moved = np.clip(q + epsilon * step / np.linalg.norm(step), robot.lower, robot.upper)
        if condition.residual(moved) >= 0.1 * epsilon:
            break
    return moved


def verify(robot: Robot, rng: np.random.Generator, samples: int = 2000, on_set: int = 200,
           epsilon: float = 1e-3, subsystem: str | None = None) -> list[Agreement]:
    """Re-run the numeric check of the conditions of one system.

    * random configurations within the limits: numeric rank < full  <=>  is_singular;
    * ``on_set`` configurations projected onto each condition: rank == the condition's rank
      and is_singular;
    * the same moved by ``epsilon`` [rad or m] in a random direction that leaves the set
      (residual >= epsilon / 10): full rank and not singular.
    """
    system = singular_system(robot, subsystem)
    name = system.name

    def rank(q: NDArray[np.float64]) -> int:
        return numeric_rank(robot, q, subsystem=name)

    random = Agreement("random configurations")
    for _ in range(samples):
        q = robot.random_configuration(rng)
        random.add((rank(q) < system.full_rank) == is_singular(robot, q, subsystem=name), q)
    reports = [random]
    for condition in system.conditions:
        exact, near = Agreement(f"on  '{condition.name}'"), Agreement(f"eps-near '{condition.name}'")
        for _ in range(50 * on_set):
            if exact.total == on_set:
                break
            on = condition.project(robot.random_configuration(rng))
            if on is None:
                continue
            exact.add(rank(on) == condition.rank and is_singular(robot, on, subsystem=name), on)
            moved = _step_off(robot, condition, on, epsilon, rng)
            near.add(rank(moved) == system.full_rank and not is_singular(robot, moved, subsystem=name), moved)
        reports += [exact, near]
    return reports


__all__ = [
    "SingularCondition", "SingularSystem", "Agreement", "RESIDUAL_TOLERANCE", "RANK_TOLERANCE",
    "analytic_conditions", "singular_system", "singular_systems", "registered_models",
    "is_singular", "scaled_jacobian", "numeric_rank", "lost_directions", "singularity_measure",
    "in_singular_region", "verify", "scorbot_measured_angles", "scorbot_dh_angles",
]
