"""``wbc warmup`` for the collision package: every kernel and op callback compiled now."""

from __future__ import annotations

from . import footprint_kernels, kernels
from .avoidance import avoidance_op
from .footprint import footprint_op


def warm_up() -> None:
    """Compile (or read from numba's cache) every kernel and op callback of the collision package
    now: the declared kernels of :mod:`~wbc.collision.kernels` and
    :mod:`~wbc.collision.footprint_kernels`, and the tick-program ops of
    :class:`~wbc.collision.CollisionAvoidance` and :class:`~wbc.collision.BaseFootprintAvoidance`."""
    from ..runtime.kernels._lazy import SIGNATURE, compile_named

    for module in (kernels, footprint_kernels):
        compile_named(module, *(name for name, value in vars(module).items() if hasattr(value, SIGNATURE)))
    avoidance_op()
    footprint_op()
