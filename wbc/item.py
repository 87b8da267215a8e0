"""What tasks and constraints have in common: the robot they are bound to, and which of
their public attributes may change once a controller uses them."""

from __future__ import annotations

from typing import Any

from .errors import InvalidInputError
from .robot import Robot


class Item:
    """Base of :class:`~wbc.tasks.task.Task` and :class:`~wbc.constraints.constraint.Constraint`.

    An item is bound once, by the first controller that uses it, to that controller's robot
    object (it resolves frame and joint names, limits, and compiled operands against it);
    further controllers of the same robot share it, a different robot object is refused.
    Once bound, public attributes change only through *settings* -- validated properties
    (gains, costs, speed bounds, ...) that act from the next tick on in every controller
    using the item; assigning anything else raises instead of being silently ignored.
    """

    name: str
    _bound_robot: Robot | None = None

    def bind(self, robot: Robot) -> None:
        """Resolve names against ``robot`` and allocate (called once, by :meth:`attach`)."""

    def attach(self, robot: Robot) -> None:
        """Bind to ``robot`` on first use; refuse a different robot object later."""
        if self._bound_robot is None:
            self.bind(robot)
            self._bound_robot = robot
        elif self._bound_robot is not robot:
            raise InvalidInputError(
                f"{self.name} is bound to another robot object ({self._bound_robot.name!r}) by an earlier "
                f"controller; an item serves the controllers of one robot: create another "
                f"{type(self).__name__} for {robot.name!r}")

    @classmethod
    def settings(cls) -> list[str]:
        """Public attributes that may be assigned at any time (validated properties)."""
        return sorted(name for name in dir(cls) if not name.startswith("_") and _is_setting(getattr(cls, name)))

    def __setattr__(self, name: str, value: Any) -> None:
        if not name.startswith("_"):
            attribute = getattr(type(self), name, None)
            if isinstance(attribute, property) and attribute.fset is None:
                raise InvalidInputError(f"{self.name}: {name} is read-only")
            if self._bound_robot is not None and not _is_setting(attribute):
                raise InvalidInputError(
                    f"{self.name}: {name} cannot change once a controller uses the item (settings that can: "
                    f"{', '.join(self.settings())}; targets go through set_target); create a new "
                    f"{type(self).__name__} instead")
        object.__setattr__(self, name, value)


def _is_setting(attribute: Any) -> bool:
    if isinstance(attribute, property):
        return attribute.fset is not None
    return hasattr(attribute, "__set__")
