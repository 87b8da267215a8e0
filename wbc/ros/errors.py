"""The errors of the ROS 2 node (:mod:`wbc.ros`), both :class:`~wbc.core.errors.WbcError`."""

from __future__ import annotations

from ..core.errors import WbcError


class RosConfigError(WbcError, ValueError):
    """A node configuration file (``--config``) is malformed or does not fit the robot."""


class RosError(WbcError, RuntimeError):
    """DDS could not be set up (``cyclonedds`` missing, a bad ``CYCLONEDDS_URI`` or ``ROS_DOMAIN_ID``)."""
