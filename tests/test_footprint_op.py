"""BaseFootprintAvoidance as an op of the tick program (wbc.collision.footprint.footprint_op): the
same rows, closest points and commands as its Python compute, every tick of a closed loop, on each
kind of base (the reduced form too), with the scan replaced every tick by a larger one (new buffers:
the op reads them through their addresses); when the op is not used."""

import numpy as np
import pytest

import wbc
from test_base_footprint import CASES, HEXAGON, deluca, random_cloud, unicycle  # noqa: F401 (fixtures)
from wbc.collision.footprint import BaseFootprintAvoidanceData
from wbc.constraints.constraint import ConstraintData


def _controllers(monkeypatch, robot, twist, q0, cloud, reduced, extra=()):
    """(op, python): the same stack, the footprint's rows as an op / from its compute."""
    def build():
        task = wbc.BaseVelocityTask(1.0)
        task.set_target(twist)
        limits = [wbc.JointVelocityLimits()] + ([wbc.NonholonomicBase()] if robot.base.is_nonholonomic else [])
        avoidance = wbc.BaseFootprintAvoidance(HEXAGON, points=cloud, min_distance=0.05, detection_distance=0.5)
        controller = wbc.Controller(robot, [task, wbc.PostureTask(1e-3, target=q0)], [*limits, avoidance, *extra],
                                    reduced=reduced)
        return controller, avoidance

    op = build()
    with monkeypatch.context() as patch:
        patch.setattr(BaseFootprintAvoidanceData, "add_ops", ConstraintData.add_ops)
        python = build()
    return op, python


def _uses_the_op(controller):
    return not any(isinstance(item, BaseFootprintAvoidanceData) for item, _ in controller._python_constraints)


@pytest.mark.parametrize("case", CASES)
def test_the_op_computes_what_compute_does_every_tick(request, monkeypatch, case):
    name, twist, reduced = CASES[case]
    robot = request.getfixturevalue(name)
    rng = np.random.default_rng(7)
    cloud = random_cloud(rng, n=400)
    q0 = robot.neutral()
    (op, op_avoidance), (python, python_avoidance) = _controllers(monkeypatch, robot, twist, q0, cloud, reduced)
    assert _uses_the_op(op) and not _uses_the_op(python)
    op_data, python_data = op.data(op_avoidance), python.data(python_avoidance)
    q, active = q0, 0
    for tick in range(150):
        if tick % 50 == 25:  # a new scan, larger than any before: set_points replaces the buffers
            cloud = random_cloud(rng, n=400 + 10 * tick)
            op_avoidance.set_points(cloud)
            python_avoidance.set_points(cloud)
        v = op.step(q)
        np.testing.assert_allclose(python.step(q), v, rtol=0, atol=1e-12)
        assert op.last.status == python.last.status
        np.testing.assert_array_equal(op_data.closest, python_data.closest)
        np.testing.assert_array_equal(op.qp.C, python.qp.C)
        np.testing.assert_array_equal(op.qp.upper, python.qp.upper)
        active += np.isfinite(op_data.closest[:, 0]).sum()
        q = robot.integrate(q, v, op.dt)
    assert active > 0  # points came within the detection distance


def test_not_used_with_acceleration_limits(youbot, monkeypatch):
    """Braking (RowBraking, with AccelerationLimits in the stack) stays in Python: the rows are computed there."""
    cloud = random_cloud(np.random.default_rng(1))
    (op, _), _ = _controllers(monkeypatch, youbot, [0.4, 0.0, 0.0], youbot.neutral(), cloud, False,
                              extra=[wbc.AccelerationLimits(max_acceleration=2.0)])
    assert not _uses_the_op(op)


def test_a_copy_reads_its_own_points(youbot, monkeypatch):
    """The op reads the points through their addresses: a copied or unpickled constraint (a copied
    controller's, the warm-up twin's) points to its own buffers, so a later scan of the original,
    which frees the old buffers, leaves the copy's ticks as they were."""
    import copy
    import pickle

    rng = np.random.default_rng(3)
    cloud = random_cloud(rng, n=300)
    (op, avoidance), _ = _controllers(monkeypatch, youbot, [0.4, 0.1, 0.2], youbot.neutral(), cloud, False)
    for other in (copy.deepcopy(avoidance), pickle.loads(pickle.dumps(avoidance))):
        assert other._grid[0] == other._ordered.ctypes.data != avoidance._ordered.ctypes.data
        assert other._grid[1] == other._cell_start.ctypes.data != avoidance._cell_start.ctypes.data
    twin = copy.deepcopy(op)
    q = youbot.neutral()
    for tick in range(40):
        if tick == 5:
            avoidance.set_points(random_cloud(rng, n=5000))  # larger: the original's buffers replaced, the old freed
        v = twin.step(q)
        q = youbot.integrate(q, v, twin.dt)
    reference, _ = _controllers(monkeypatch, youbot, [0.4, 0.1, 0.2], youbot.neutral(), cloud, False)
    q_ref = youbot.neutral()
    for _ in range(40):
        q_ref = youbot.integrate(q_ref, reference[0].step(q_ref), twin.dt)
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-12)  # the twin kept the first cloud
