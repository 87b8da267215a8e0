"""Scorbot-ER 4pc angle conventions (Gierlak 2014, eq. 14).

wbc's ``scorbot_er4pc`` model uses the DH joint angles ``theta`` of Gierlak's Table 1
(theta3, theta4 relative to the previous link). The robot's controller, and Gierlak's
Jacobians (15), (19), use the *measured* angles ``q`` of eq. (14), in which links 3 and 4
are measured from the horizontal plane x0 y0::

    q = (theta1, theta2, theta2 + theta3, theta2 + theta3 + theta4, theta5)

so q2, q3, q4 are the elevations of the upper arm, the forearm and the tool axis. The map
is linear with determinant 1, so it changes no Jacobian rank.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import as_vector

_DH_TO_MEASURED = np.array([
    [1, 0, 0, 0, 0],
    [0, 1, 0, 0, 0],
    [0, 1, 1, 0, 0],
    [0, 1, 1, 1, 0],
    [0, 0, 0, 0, 1],
], dtype=np.float64)
_MEASURED_TO_DH = np.linalg.inv(_DH_TO_MEASURED)


def scorbot_measured_angles(theta: ArrayLike) -> NDArray[np.float64]:
    """Gierlak's measured angles q (eq. 14) from the DH angles theta of the model."""
    return _DH_TO_MEASURED @ as_vector(theta, 5, "theta")


def scorbot_dh_angles(q: ArrayLike) -> NDArray[np.float64]:
    """DH angles theta of the model from the measured angles q: theta3 = q3 - q2, theta4 = q4 - q3."""
    return _MEASURED_TO_DH @ as_vector(q, 5, "q")


__all__ = ["scorbot_measured_angles", "scorbot_dh_angles"]
