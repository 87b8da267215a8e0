"""CollisionAvoidance as an op of the tick program (wbc.collision.avoidance.avoidance_op): the same
rows, counts and commands as its Python compute, every tick of a closed loop; when it is not used."""

import numpy as np
import pytest

import wbc
from wbc.collision.avoidance import CollisionAvoidanceData, compiled_pairs_only
from wbc.constraints.constraint import ConstraintData

YOUBOT = wbc.load_robot("youbot")
NEUTRAL = YOUBOT.neutral()
EE = YOUBOT.frame_pose(NEUTRAL, "ee")[:3, 3]


def _obstacles():
    """A sphere across the gripper's path to its target, a capsule, a floor: pairs within reach."""
    return [wbc.Sphere(EE + (0.12, 0.0, 0.0), 0.05), wbc.Capsule(EE + (0.0, 0.25, -0.2), EE + (0.0, 0.25, 0.2), 0.03),
            wbc.Plane((0.0, 0.0, 1.0), -0.25)]


def _controller(constraints, solver="daqp"):
    ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.0, gain=0.5, max_speed=0.5)
    pose = YOUBOT.frame_pose(NEUTRAL, "ee")
    pose[:3, 3] = EE + (0.3, 0.05, 0.0)  # past the sphere
    ee.set_target(pose)
    return wbc.Controller(YOUBOT, [ee, wbc.PostureTask(cost=1e-3, gain=0.05)],
                          [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), *constraints], solver=solver)


def _in_python(monkeypatch, constraints, solver="daqp"):
    """The same controller with the constraint's rows computed in Python (its compute)."""
    with monkeypatch.context() as patch:
        patch.setattr(CollisionAvoidanceData, "add_ops", ConstraintData.add_ops)
        return _controller(constraints, solver)


def _uses_the_op(controller):
    return not any(isinstance(item, CollisionAvoidanceData) for item, _ in controller._python_constraints)


@pytest.mark.parametrize("solver", ["daqp", "osqp"])
def test_the_op_computes_what_compute_does_every_tick(monkeypatch, solver):
    avoidance = wbc.CollisionAvoidance(_obstacles(), self_collision=True, min_distance=0.02, gain=0.5)
    native, python = _controller([avoidance], solver), _in_python(monkeypatch, [avoidance], solver)
    assert _uses_the_op(native) and not _uses_the_op(python)
    assert (native._stepper is not None) == (solver == "daqp")  # the whole tick one native call with native DAQP
    native_data, python_data = native.data(avoidance), python.data(avoidance)
    q = NEUTRAL.copy()
    binding = 0
    for _ in range(250):
        v = native.step(q)
        np.testing.assert_allclose(python.step(q), v, rtol=0, atol=1e-9)
        assert native.last.status == python.last.status
        for data in (native_data, python_data):
            assert data.pairs.count > 0
        assert native_data.pairs.count == python_data.pairs.count and native_data.corners == python_data.corners
        assert native_data.active_labels() == python_data.active_labels()
        assert native_data.row_labels() == python_data.row_labels()
        assert native_data.min_distance == pytest.approx(python_data.min_distance, abs=1e-12)
        count = native_data.pairs.count
        np.testing.assert_allclose(native_data.pairs.distance[:count], python_data.pairs.distance[:count], atol=1e-12)
        np.testing.assert_allclose(native_data.pairs.rows[:count], python_data.pairs.rows[:count], atol=1e-12)
        binding += any("sphere0" in label for label in native.active_constraints(v))
        q = YOUBOT.integrate(q, v, 0.01)
    assert binding > 10  # the sphere's rows bound the command
    assert native_data.min_distance >= 0.02 - 2e-3


def test_the_op_reads_obstacles_moved_between_ticks(monkeypatch):
    spheres = [wbc.Sphere(EE + (0.4, 0.0, 0.0), 0.05) for _ in range(2)]
    avoidances = [wbc.CollisionAvoidance([sphere], self_collision=False, min_distance=0.02) for sphere in spheres]
    native, python = _controller([avoidances[0]]), _in_python(monkeypatch, [avoidances[1]])
    assert _uses_the_op(native)
    q, closest = NEUTRAL.copy(), []
    step = 0.001  # [m] per tick: 0.1 m/s
    for k in range(300):  # the sphere drifts onto the gripper, the rows follow it
        for sphere in spheres:
            sphere.center = EE + (0.4 - step * k, 0.0, 0.0)
        v = native.step(q)
        np.testing.assert_allclose(python.step(q), v, rtol=0, atol=1e-9)
        closest.append(native.data(avoidances[0]).min_distance)
        q = YOUBOT.integrate(q, v, 0.01)
    assert min(closest) < 0.05  # the sphere came close, and the margin held (the dampers see the obstacle
    # still: one that approaches costs up to step / gain of the margin)
    assert min(closest) >= 0.02 - step / 0.5 - 1e-3


def test_the_op_is_not_used_where_python_or_coal_is_needed():
    box_pose = np.eye(4)
    box_pose[:3, 3] = (0.6, 0.0, 0.3)
    with_box = wbc.CollisionAvoidance([wbc.Box(box_pose, (0.1, 0.1, 0.1))])  # box-box: compiled, overlap too
    assert _uses_the_op(_controller([with_box]))
    braking = wbc.CollisionAvoidance(_obstacles())
    accelerations = wbc.AccelerationLimits(max_acceleration=5.0)
    assert not _uses_the_op(_controller([braking, accelerations]))  # the braking bound is computed in Python
    assert _uses_the_op(_controller([wbc.CollisionAvoidance(_obstacles())]))


def test_compiled_pairs_only_refuses_coal_shapes():
    box_pose = np.eye(4)
    assert compiled_pairs_only(wbc.collision.Distances(YOUBOT, _obstacles()))
    assert compiled_pairs_only(wbc.collision.Distances(YOUBOT, [wbc.Box(box_pose, (0.1, 0.1, 0.1))]))
    distances = wbc.collision.Distances(YOUBOT, [wbc.Sphere((1.0, 0.0, 0.3), 0.1)])
    distances.table[0, 0] = 5.0  # the platform as a shape coal measures (a mesh, a cylinder)
    assert not compiled_pairs_only(distances)
