"""What tasks and constraints have in common: a *specification* (settings) that the
controllers using it turn into per-controller *data* (Pinocchio's Model/Data split)."""

from __future__ import annotations

from typing import Any

from .errors import InvalidInputError
from .robot import Robot


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

    A simple custom item may be its own data (the default :meth:`bind` returns ``self``):
    then it serves the controllers of one robot object only, and what it computes per
    tick is shared by them.
    """

    name: str
    _in_use = False  # set when a controller binds the item: from then on only settings change
    _own_robot: Robot | None = None  # the robot of an item that is its own data

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

    @classmethod
    def settings(cls) -> list[str]:
        """Public attributes that may be assigned at any time (validated properties)."""
        return sorted(name for name in dir(cls) if not name.startswith("_") and _is_setting(getattr(cls, name)))

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
