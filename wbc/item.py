"""What tasks and constraints have in common: a *specification* (settings) that the
controllers using it turn into per-controller *data* (Pinocchio's Model/Data split)."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any, ClassVar, NamedTuple

import numpy as np

from .core.errors import InvalidInputError
from .model.robot import Robot


class Item:
    """Base of :class:`~wbc.tasks.task.Task` and :class:`~wbc.constraints.constraint.Constraint`.

    An item is a specification: what to achieve or respect, with which settings. Each
    controller that uses it calls :meth:`bind` once, which resolves the item against that
    controller's robot (frame and joint indices, limits, buffers) and returns the item's
    *data* for that controller. Several controllers, of one robot or of several, may share
    an item: each has its own data, and the item's settings -- validated properties
    (costs, gains, speed bounds, targets through ``set_target``) -- act from the next tick
    on in all of them. Once a controller uses the item, assigning any other public
    attribute raises instead of being silently ignored.

    A class that subclasses both the item and its data class (``class T(Task, TaskData)``) is its
    own data (:meth:`bind` returns ``self``): it then serves the controllers of one robot object
    only, and what it computes per tick is shared by them.

    **Copies.** ``copy.copy``, ``copy.deepcopy`` and pickling give a new item with the same
    settings, independent of the original and used by no controller yet (``__getstate__``):
    its settings act in the controllers built with it, and changing them leaves the original
    alone. An attribute that is a view into another array attribute (the settings of
    :class:`~wbc.tasks.FrameTask` are views into the one vector its kernel reads) is a view
    into the copy's array again.
    """

    name: str
    _in_use = False  # set when a controller binds the item: from then on only settings change
    _own_robot: Robot | None = None  # the robot of an item that is its own data
    #: attributes that record the controllers using the item, not part of its specification: a
    #: copy starts with their value for a new item (name -> factory of that value)
    _bindings: ClassVar[dict[str, Callable[[], Any]]] = {"_in_use": lambda: False, "_own_robot": lambda: None}

    def bind(self, robot: Robot) -> Any:
        """This item's data for a controller of ``robot`` (default: the item itself, which
        then serves one robot object)."""
        if self._own_robot is None:
            self._own_robot = robot
        elif self._own_robot is not robot:
            raise InvalidInputError(
                f"{self.name} is its own per-controller data and is bound to another robot object "
                f"({self._own_robot.name!r}); create another {type(self).__name__} for {robot.name!r}")
        return self

    def bind_as_own_data(self, robot: Robot, data: type, base: str, advice: str) -> Any:
        """What :meth:`bind` of a Task / Constraint (``base``) does by default: the item itself if it
        declares itself its own data (an instance of the ``data`` class), else InvalidInputError
        naming the fix (``advice``: where its rows may come from)."""
        if isinstance(self, data):
            return Item.bind(self, robot)
        name = type(self).__name__
        if hasattr(self, "compute"):  # an item written for wbc <= 0.3, where every item was its own data
            raise InvalidInputError(f"{name} defines compute() but is not a {data.__name__}: declare it "
                                    f"`class {name}({base}, {data.__name__})` to be its own data, or move compute() "
                                    f"into a {data.__name__} subclass returned by bind() (docs/extending.md)")
        raise InvalidInputError(f"{name} computes no rows: {advice} (docs/extending.md)")

    @classmethod
    def settings(cls) -> list[str]:
        """Public attributes that may be assigned at any time (validated properties)."""
        return sorted(name for name in dir(cls) if not name.startswith("_") and _is_setting(getattr(cls, name)))

    def __getstate__(self) -> dict[str, Any]:
        """The specification (for copies and pickles): the attributes without the bindings, an
        array attribute that views another one as an :class:`ArrayView` of it."""
        state = {name: value for name, value in self.__dict__.items() if name not in self._bindings}
        owners = {id(value): name for name, value in state.items()
                  if isinstance(value, np.ndarray) and value.base is None}
        for name, value in state.items():
            if isinstance(value, np.ndarray) and isinstance(value.base, np.ndarray) and id(value.base) in owners:
                state[name] = ArrayView.of(value, value.base, owners[id(value.base)])
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore :meth:`__getstate__`'s specification: views into the restored arrays, fresh
        bindings (used by no controller)."""
        for name, value in state.items():
            object.__setattr__(self, name, value.view_of(state[value.owner]) if isinstance(value, ArrayView) else value)
        for name, fresh in self._bindings.items():
            object.__setattr__(self, name, fresh())

    def __copy__(self) -> Item:
        """A copy independent of this item (a deep copy: a shallow one would share the settings
        arrays, and changing the copy's settings would change the original's)."""
        return copy.deepcopy(self)

    def __setattr__(self, name: str, value: Any) -> None:
        if not name.startswith("_"):
            attribute = getattr(type(self), name, None)
            if isinstance(attribute, property) and attribute.fset is None:
                raise InvalidInputError(f"{self.name}: {name} is read-only")
            if self._in_use and not _is_setting(attribute):
                raise InvalidInputError(
                    f"{self.name}: {name} cannot change once a controller uses the item (settings that can: "
                    f"{', '.join(self.settings())}; targets go through set_target); create a new "
                    f"{type(self).__name__} instead")
        object.__setattr__(self, name, value)


def _is_setting(attribute: Any) -> bool:
    if isinstance(attribute, property):
        return attribute.fset is not None
    return hasattr(attribute, "__set__")


class ArrayView(NamedTuple):
    """Where an array attribute of an item lies in another one (its ``owner``), for copies."""

    owner: str
    offset: int  #: [bytes] from the owner's first element
    shape: tuple[int, ...]
    strides: tuple[int, ...]

    @classmethod
    def of(cls, view: np.ndarray, base: np.ndarray, owner: str) -> ArrayView:
        """``view``'s place in its ``base``, the attribute ``owner`` (a C-contiguous array)."""
        if not base.flags.c_contiguous:
            raise InvalidInputError(f"cannot copy an item whose array {owner!r} is not C-contiguous and has views")
        offset = view.__array_interface__["data"][0] - base.__array_interface__["data"][0]
        return cls(owner, offset, view.shape, view.strides)

    def view_of(self, owner: np.ndarray) -> np.ndarray:
        """The same view into ``owner`` (the owner's copy)."""
        return np.ndarray(self.shape, owner.dtype, buffer=owner, offset=self.offset, strides=self.strides)
