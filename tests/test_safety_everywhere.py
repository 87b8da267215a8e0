"""Issue 24, "Everywhere": collision avoidance holds in a strict hierarchy (at every level of the
cascade) and in the reduced nonholonomic form (solved over the wheels' inputs), checked every
tick against coal (Pinocchio's computeDistances on the URDF's raw shapes)."""

import numpy as np
import pytest

import wbc
from test_collision_avoidance import EE, LIMITS, MIN_DISTANCE, NEUTRAL, TOLERANCE, YOUBOT, _excluded, _run
from test_collision_distances import Oracle


@pytest.mark.parametrize("solver", ["daqp", "proxqp"])
def test_a_two_level_hierarchy_keeps_the_margin(solver):
    """The gripper's reach through a sphere at the top level, a posture below: the collision rows
    bind both levels (the top level's answer already goes around the sphere)."""
    sphere = wbc.Sphere(EE + (0.15, 0.0, -0.05), 0.05)
    target = EE + (0.3, 0.0, -0.1)
    ee = wbc.PositionTask("ee", gain=0.5, max_speed=0.5)
    ee.set_target(target)
    controller = wbc.Controller(YOUBOT, [[ee], [wbc.PostureTask(cost=1e-3, gain=0.05)]],
                                [*LIMITS, wbc.CollisionAvoidance([sphere])], solver=solver)
    oracle, excluded = Oracle(YOUBOT, [sphere]), _excluded(YOUBOT)
    q, closest, _ = _run(controller, NEUTRAL, 300, oracle, excluded)
    assert closest.min() >= MIN_DISTANCE - TOLERANCE
    assert np.linalg.norm(YOUBOT.frame_pose(q, "ee")[:3, 3] - target) < 1e-3  # it went around


def test_the_reduced_nonholonomic_form_keeps_the_margin():
    """De Luca's synchro-drive manipulator solved over its real inputs (``reduced=True``): its
    wrist's straight path to the goal passes through a sphere; the margin holds, the no-slip
    motion too (the base moves only along its heading)."""
    robot = wbc.load_robot("deluca_mm")
    q0 = np.array([0.0, 0.0, 0.0, 0.3, 0.4, 0.2])
    start = robot.frame_pose(q0, "wrist_center")[:3, 3]
    goal = start + (0.4, 0.0, 0.0)
    sphere = wbc.Sphere(start + (0.2, 0.0, 0.0), 0.04)
    wrist = wbc.PositionTask("wrist_center", gain=0.3, max_speed=0.3)
    wrist.set_target(goal)
    constraints = [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.NonholonomicBase(),
                   wbc.CollisionAvoidance([sphere], self_collision=False)]
    controller = wbc.Controller(robot, [wrist, wbc.PostureTask(cost=1e-3)], constraints, reduced=True)
    unguarded = wbc.Controller(robot, [wrist, wbc.PostureTask(cost=1e-3)], constraints[:3], reduced=True)
    oracle = Oracle(robot, [sphere])
    obstacle_pairs = {key for key in oracle.distances(q0) if any("obstacle" in part for part in key)}

    def closest_to_sphere(q):
        distances = oracle.distances(q)
        return min(distances[key] for key in obstacle_pairs)

    q, slip = q0.copy(), 0.0
    closest = []
    for _ in range(400):
        v = controller.step(q)
        slip = max(slip, abs(robot.base_twist(q, v)[1]))
        q = robot.integrate(q, v, controller.dt)
        closest.append(closest_to_sphere(q))
    unguarded_q = q0.copy()
    unguarded_closest = []
    for _ in range(400):
        unguarded_q = robot.integrate(unguarded_q, unguarded.step(unguarded_q), unguarded.dt)
        unguarded_closest.append(closest_to_sphere(unguarded_q))
    assert min(unguarded_closest) < 0.0  # the sphere is in the way
    assert min(closest) >= MIN_DISTANCE - TOLERANCE
    assert slip < 1e-9
