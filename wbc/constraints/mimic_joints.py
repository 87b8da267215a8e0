"""Coupled joints move together: ``v_joint = multiplier v_leader`` (URDF ``<mimic>``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..core.errors import InvalidInputError
from ..model.couplings import JointCoupling, check_couplings
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime.program import TickProgram
from .constraint import Constraint, ConstraintData, ConstraintRows


class MimicJoints(Constraint):
    """One equality row per coupling ``q_joint = multiplier q_leader + offset``::

        v_joint - multiplier v_leader = 0

    so a coupling that holds at the start holds all along (a parallel gripper's second finger
    follows the first). Every :class:`wbc.Controller` of a robot with couplings
    (``robot.couplings``: the URDF's ``<mimic>`` joints) adds it; give it yourself to couple
    other joints (``couplings=[("joint", "leader", multiplier)]``). A hard constraint:
    ``v = 0`` satisfies it.

    Args:
        couplings: ``(joint, leader, multiplier)`` triples or
            :class:`~wbc.model.couplings.JointCoupling`; None: the robot's own.
    """

    def __init__(self, couplings: Sequence[JointCoupling | tuple[str, str, float]] | None = None,
                 name: str | None = None) -> None:
        super().__init__(name)
        self.couplings = None if couplings is None else tuple(_coupling(item) for item in couplings)

    def bind(self, robot: Robot) -> MimicJointsData:
        return MimicJointsData(self, robot)

    def __repr__(self) -> str:
        return f"MimicJoints(couplings={self.couplings!r})"


def _coupling(item: JointCoupling | tuple[str, str, float]) -> JointCoupling:
    if isinstance(item, JointCoupling):
        return item
    if not (isinstance(item, Sequence) and len(item) == 3 and all(isinstance(name, str) for name in item[:2])
            and isinstance(item[2], (int, float)) and not isinstance(item[2], bool)):
        raise InvalidInputError(f"a coupling is a (joint, leader, multiplier) triple, got {item!r}")
    return JointCoupling(item[0], item[1], float(item[2]))


class MimicJointsData(ConstraintData):
    """:class:`MimicJoints` in one controller: the constant rows ``e_joint - multiplier e_leader``."""

    def __init__(self, mimic: MimicJoints, robot: Robot) -> None:
        super().__init__(mimic)
        self.couplings = robot.couplings if mimic.couplings is None else mimic.couplings
        check_couplings(robot.model, self.couplings, mimic.name)
        model = robot.model
        self.matrix = np.zeros((len(self.couplings), robot.nv))
        for row, coupling in enumerate(self.couplings):
            self.matrix[row, model.joints[model.getJointId(coupling.joint)].idx_v] = 1.0
            self.matrix[row, model.joints[model.getJointId(coupling.leader)].idx_v] -= coupling.multiplier
        self.n_equalities = len(self.couplings)

    def write_static(self, rows: ConstraintRows) -> None:
        rows.A[...] = self.matrix
        rows.b[...] = 0.0

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        return True  # static rows: nothing to do per tick

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        """The rows are static (:meth:`write_static`)."""

    def row_labels(self) -> list[str]:
        return [f"{c.joint} = {c.multiplier:g} {c.leader}" for c in self.couplings]
