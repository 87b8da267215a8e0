"""Settings of tasks and constraints: validated attributes that may change between ticks.

Four descriptors, for the places a setting can live:

* :class:`Setting` -- a plain attribute (read by Python code each tick);
* :class:`Operand` -- one slot of an operand array that a compiled op reads;
* :class:`Cost` -- a cost stored as its square root (row weights) in a slice of such an array;
* :class:`UniformCost` -- one scalar cost for every row of such an array.

Each validates on assignment (``check(value, name)``, from :mod:`wbc.core.validation`) and the new
value acts from the next tick on, in every controller using the item; :class:`wbc.item.Item`
lets these (and properties with setters) be assigned after a controller uses the item.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Generic, TypeVar, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .validation import as_nonnegative, as_weights

_In = TypeVar("_In")  # what an assignment takes (the check's argument)
_Out = TypeVar("_Out")  # what a read gives (the check's result)


class Setting(Generic[_In, _Out]):
    """A validated setting kept on the instance: ``gain = Setting(as_gain)`` makes
    ``task.gain = x`` store ``as_gain(x, "gain")`` (raising on bad input) in ``task._gain``."""

    def __init__(self, check: Callable[[_In, str], _Out]) -> None:
        self._check = check

    def __set_name__(self, owner: type, name: str) -> None:
        self._name, self._slot = name, f"_{name}"

    @overload
    def __get__(self, instance: None, owner: type | None = None) -> Setting[_In, _Out]: ...
    @overload
    def __get__(self, instance: object, owner: type | None = None) -> _Out: ...
    def __get__(self, instance: object, owner: type | None = None) -> Setting[_In, _Out] | _Out:
        if instance is None:
            return self
        return getattr(instance, self._slot)

    def __set__(self, instance: object, value: _In) -> None:
        setattr(instance, self._slot, self._check(value, self._name))


class Operand(Generic[_In]):
    """A scalar setting that lives in an operand array of a compiled op.

    ``gain = Operand("_parameters", 36, as_gain)`` makes ``task.gain`` read and write slot
    36 of ``task._parameters``, validated by ``check(value, name)`` on every assignment, so
    tuning a setting between ticks reaches the compiled code.
    """

    def __init__(self, array: str, index: int, check: Callable[[_In, str], float]) -> None:
        self._array, self._index, self._check = array, index, check

    def __set_name__(self, owner: type, name: str) -> None:
        self._name = name

    @overload
    def __get__(self, instance: None, owner: type | None = None) -> Operand[_In]: ...
    @overload
    def __get__(self, instance: object, owner: type | None = None) -> float: ...
    def __get__(self, instance: object, owner: type | None = None) -> Operand[_In] | float:
        if instance is None:
            return self
        return float(getattr(instance, self._array)[self._index])

    def __set__(self, instance: object, value: _In) -> None:
        getattr(instance, self._array)[self._index] = self._check(value, self._name)


class Cost:
    """A cost setting stored as its square root (the row weights ``W = sqrt(cost)``) in a
    slice of an operand array: ``position_cost = Cost("_weights", slice(0, 3))``.

    Reads give the cost vector; assignments are validated (scalar or one per row, finite,
    >= 0) and act from the next tick on, in every controller that uses the item.
    """

    def __init__(self, array: str, rows: slice) -> None:
        self._array, self._rows = array, rows

    def __set_name__(self, owner: type, name: str) -> None:
        self._name = name

    @overload
    def __get__(self, instance: None, owner: type | None = None) -> Cost: ...
    @overload
    def __get__(self, instance: object, owner: type | None = None) -> NDArray[np.float64]: ...
    def __get__(self, instance: object, owner: type | None = None) -> Cost | NDArray[np.float64]:
        if instance is None:
            return self
        return instance.__dict__[self._name].copy()

    def __set__(self, instance: object, value: ArrayLike) -> None:
        weights = getattr(instance, self._array)[self._rows]
        cost = as_weights(value, len(weights), self._name)
        weights[...] = np.sqrt(cost)
        instance.__dict__[self._name] = cost  # what was asked, without the rounding of sqrt


class UniformCost:
    """One scalar cost for every row, stored as its square root in the whole operand array:
    ``cost = UniformCost("_weights")``. Reads give the cost (a float); assignments are validated
    (finite, >= 0) and act from the next tick on. The array is looked up at each assignment, so
    an item may replace it (resize its rows) before a controller uses it."""

    def __init__(self, array: str) -> None:
        self._array = array

    def __set_name__(self, owner: type, name: str) -> None:
        self._name = name

    @overload
    def __get__(self, instance: None, owner: type | None = None) -> UniformCost: ...
    @overload
    def __get__(self, instance: object, owner: type | None = None) -> float: ...
    def __get__(self, instance: object, owner: type | None = None) -> UniformCost | float:
        if instance is None:
            return self
        return float(instance.__dict__[self._name])

    def __set__(self, instance: object, value: float) -> None:
        cost = as_nonnegative(value, self._name)
        getattr(instance, self._array)[...] = math.sqrt(cost)
        instance.__dict__[self._name] = cost
