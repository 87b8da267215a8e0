"""A base bolted to the world: no base coordinates, the inputs are the joint rates."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ...core.errors import InvalidInputError
from .interface import BaseKind, MobileBase


@dataclass(frozen=True)
class FixedBase(MobileBase):
    """No base motion: ``indices`` are ``(-1, -1, -1)``, no rows, ``S = I``."""

    kind: BaseKind = BaseKind.FIXED
    indices: tuple[int, int, int] = (-1, -1, -1)

    is_mobile: ClassVar[bool] = False

    @property
    def is_nonholonomic(self) -> bool:
        return False

    def limit_coordinates(self, lower: NDArray[np.float64], upper: NDArray[np.float64],
                          velocity_limit: NDArray[np.float64]) -> None:
        """Nothing to limit: every coordinate is a joint of the arm."""

    def twist(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        raise InvalidInputError("a fixed base has no twist")


#: the base of every robot without one
FIXED_BASE = FixedBase()

__all__ = ["FixedBase", "FIXED_BASE"]
