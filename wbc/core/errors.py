"""Exception hierarchy of wbc: every error the library raises derives from WbcError."""

from __future__ import annotations


class WbcError(Exception):
    """Base class of all wbc errors."""


class InvalidInputError(WbcError, ValueError):
    """An argument has the wrong shape, dtype or a non-finite / out-of-domain value."""


class UnknownFrameError(WbcError, LookupError):
    """A frame name is not part of the robot model."""


class UnknownSolverError(WbcError, ValueError):
    """A QP solver name is not one that qpsolvers finds installed."""


class ModelError(WbcError):
    """A robot description could not be found or is inconsistent."""


class ModelWarning(UserWarning):
    """A robot model loads, but with something wbc does not model (a mobile robot loaded with a
    fixed base, URDF mimic joints): the message names the fix."""


class ConfigurationWarning(UserWarning):
    """A controller builds, but a setting defeats what it is for (a collision detection distance
    shorter than the braking distance its acceleration bounds imply): the message names the fix."""


class ScenarioError(WbcError, ValueError):
    """A scenario file (``tasks/*.toml``) is malformed."""


class SolverError(WbcError, RuntimeError):
    """The QP solver failed or returned a non-finite solution."""


class PlanningError(WbcError, RuntimeError):
    """A trajectory could not be planned (IK failed, or no detour clears the singular region)."""
