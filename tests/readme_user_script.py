"""A user's script written like the README (its first snippet, then the control loop of "Using
wbc in a control loop"), for tests/test_typing.py: type-checked in strict mode, never run.

The driver functions of the control loop are the user's own, typed as a user would type them.
``reveal_type`` lines state the types a user's checker must see.
"""

import numpy as np
from numpy.typing import NDArray
from typing_extensions import reveal_type

import wbc

# ------------------------------------------------------------------ the README's first snippet
robot = wbc.load_robot("youbot")  # or any URDF path
ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.5, gain=0.5)
controller = wbc.Controller(
    robot,
    tasks=[ee, wbc.PostureTask(cost=1e-3, gain=0.05)],
    constraints=[wbc.JointPositionLimits(gain=0.5), wbc.JointVelocityLimits()],
    solver="daqp",
    dt=0.01,
)
q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])  # (X_C, Y_C, θ, θ1..θ5)
target = robot.frame_pose(q, "ee")
target[:3, 3] += [0.3, 0.2, 0.0]
ee.set_target(target)  # 4x4 world pose (+ optional feed-forward twist)
for _ in range(500):
    v = controller.step(q)  # shape (nv,), never NaN
    q = robot.integrate(q, v, controller.dt)
print(controller.last)  # status, solve time, task errors, active constraints

reveal_type(robot.frame_pose)
reveal_type(ee.set_target)
reveal_type(controller.step)
reveal_type(robot.integrate)
reveal_type(controller.dt)
reveal_type(controller.last)
reveal_type(target)
reveal_type(controller.step(q))
reveal_type(q)


# ------------------------------------------------------- "Using wbc in a control loop"
def running() -> bool:
    raise NotImplementedError


def read_joint_positions() -> NDArray[np.float64]:
    raise NotImplementedError


def target_pose() -> NDArray[np.float64]:
    raise NotImplementedError


def log(message: str) -> None:
    raise NotImplementedError


def send_wheel_speeds(speeds: NDArray[np.float64]) -> None:
    raise NotImplementedError


def send_arm_velocities(velocities: NDArray[np.float64]) -> None:
    raise NotImplementedError


class RateLimiter:  # loop_rate_limiters.RateLimiter, an optional package the README names
    def __init__(self, frequency: float) -> None:
        raise NotImplementedError

    def sleep(self) -> None:
        raise NotImplementedError


robot = wbc.load_robot("youbot")
ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.5, gain=0.5)
controller = wbc.Controller(
    robot, [ee, wbc.PostureTask(cost=1e-3, gain=0.05)],
    [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()],
    dt=0.01, solver_options={"time_limit": 2e-3},  # DAQP: at most 2 ms per solve
)
rate = RateLimiter(frequency=100.0)
while running():
    q = read_joint_positions()  # your driver: (X_C, Y_C, θ, θ1..θ5)
    ee.set_target(target_pose())  # 4x4 world pose (+ optional feed-forward twist)
    v = controller.step(q)  # shape (8,), finite, within the hard limits
    if not controller.last.success:
        log(controller.last.status)  # what failed and which fallback answered
    send_wheel_speeds(robot.wheel_speeds(q, v))  # rad/s, (FL, FR, RL, RR)
    send_arm_velocities(v[3:])  # rad/s
    rate.sleep()

reveal_type(controller.last.success)
reveal_type(controller.last.status)
reveal_type(robot.wheel_speeds(q, controller.step(q)))
