"""wbc -- QP-based whole-body velocity control for mobile manipulators.

Data flows one way each tick::

    Robot (model)  ->  Kinematics (computed once)  ->  tasks + constraints
                   ->  QP (preallocated)  ->  solver  ->  command v + Controller.last

Conventions: see :mod:`wbc.model.robot` (frames, Jacobians, twists) and :mod:`wbc.model.mobile_base`
(base pose and base-frame twists).
"""

from .runtime import kernels as _kernels

_kernels.start_compiling()  # a first start after an install: compile workers begin with the common kernels

from .collision import BaseFootprintAvoidance, Box, Capsule, CollisionAvoidance, Plane, Sphere
from .constraints import (
    AccelerationLimits,
    Constraint,
    DofFreezing,
    JointPositionLimits,
    JointVelocityLimits,
    LinearConstraint,
    ManipulabilityBarrier,
    MecanumWheelLimits,
    MimicJoints,
    NonholonomicBase,
    SupportPolygon,
    WheelSpeedLimits,
)
from .control.controller import Controller
from .control.diagnostics import TickDiagnostics
from .core.errors import (
    ConfigurationWarning,
    InvalidInputError,
    ModelError,
    ModelWarning,
    PlanningError,
    ScenarioError,
    SolverError,
    UnknownFrameError,
    UnknownSolverError,
    WbcError,
)
from .core.outcome import Outcome
from .model.manipulability import Manipulability, manipulability, manipulability_gradient
from .model.mobile_base import BaseKind, DifferentialWheels, MecanumWheels, MobileBase
from .model.robot import Robot, load_robot, model_path, shipped_models
from .qp.problem import QP
from .solvers import available_solvers
from .tasks import (
    AxisAlignTask,
    BaseVelocityTask,
    CoMTask,
    DampingTask,
    FrameTask,
    KineticEnergyRegularization,
    LinearCost,
    LinearTask,
    LookAtTask,
    ManipulabilityGradient,
    ManipulabilityTask,
    PositionTask,
    PostureTask,
    RelativeFrameTask,
    SteeringTask,
    Task,
)

__version__ = "0.3.0"

__all__ = [
    "BaseKind", "DifferentialWheels", "MecanumWheels", "MobileBase",
    "Constraint", "JointPositionLimits", "JointVelocityLimits", "ManipulabilityBarrier", "MecanumWheelLimits",
    "NonholonomicBase", "WheelSpeedLimits", "SupportPolygon", "DofFreezing", "AccelerationLimits", "MimicJoints",
    "LinearConstraint",
    "CollisionAvoidance", "Sphere", "Box", "Capsule", "Plane", "BaseFootprintAvoidance",
    "Manipulability", "manipulability", "manipulability_gradient",
    "Controller", "TickDiagnostics", "Outcome", "QP",
    "ConfigurationWarning", "InvalidInputError", "ModelError", "ModelWarning", "PlanningError", "ScenarioError",
    "SolverError", "UnknownFrameError", "UnknownSolverError", "WbcError",
    "Robot", "load_robot", "model_path", "shipped_models", "available_solvers",
    "Task", "FrameTask", "PositionTask", "PostureTask", "BaseVelocityTask", "SteeringTask", "ManipulabilityTask",
    "RelativeFrameTask", "CoMTask", "DampingTask", "KineticEnergyRegularization", "LookAtTask", "AxisAlignTask",
    "LinearTask", "LinearCost", "ManipulabilityGradient",
]
