"""The pairs' reach at every configuration (wbc.collision.reach.lever_bounds): each coordinate's
lever on a shape, bounded once per pair, is at least its lever at any configuration (Pinocchio's
joint Jacobians, the formula written out here), on the youBot and on chains of every joint kind
the bound knows; the kernel forms the pairs' reach from the speed bound again when it changes."""

import numpy as np
import pinocchio as pin
import pytest

import wbc
from conftest import pair_levers
from wbc.collision.distances import _support
from wbc.collision.layout import BOUND_CENTER, BOUND_RADIUS, JOINT, KIND, ROTATION, ROW, SPHERE, TRANSLATION
from wbc.collision.reach import lever_bounds
from wbc.constraints.constraint import ConstraintRows
from wbc.model.kinematics import Kinematics

YOUBOT = wbc.load_robot("youbot")


def _levers_at(model, table, pairs, q):
    """``|v_O,k + w_k x c| + |w_k| r`` for every pair and coordinate that moves exactly one of its
    shapes (c, r: that shape's bounding sphere, world), NaN for the others (conftest.pair_levers)."""
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    return np.array([pair_levers(model, data, table, int(a), int(b))[0] for a, b, _ in pairs])


def test_the_youbot_levers_bound_every_configuration_and_are_finite(rng):
    distances = wbc.collision.Distances(YOUBOT, [wbc.Sphere((0.6, 0.1, 0.3), 0.05)])
    model, table, pairs = YOUBOT.model, distances.table, distances.pairs
    bounds = distances.levers
    assert np.all(np.isfinite(bounds))  # revolute and prismatic joints only: every lever bounded
    largest = np.zeros_like(bounds)
    for _ in range(150):  # anywhere, not only within the limits: the bound holds at every configuration
        q = pin.neutral(model)
        q[:2] = rng.uniform(-3.0, 3.0, 2)
        q[2:] = rng.uniform(-np.pi, np.pi, model.nq - 2)
        levers = _levers_at(model, table, pairs, q)
        moving = ~np.isnan(levers)
        np.testing.assert_array_equal(bounds[~moving], 0.0)  # 0 exactly where a coordinate moves both or neither
        assert np.all(levers[moving] <= bounds[moving] * (1.0 + 1e-12)), np.max(levers[moving] / bounds[moving])
        largest = np.maximum(largest, np.nan_to_num(levers))
    assert np.any(largest > 0.95 * bounds)  # reached at some configurations: not a loose constant


def _chain(root: str) -> pin.Model:
    """A chain of every joint kind the bound knows, a prismatic joint near its end, behind ``root``."""
    model = pin.Model()
    rng = np.random.default_rng(3)

    def placement():
        return pin.SE3(pin.exp3(rng.normal(size=3)), rng.uniform(-0.3, 0.3, 3))

    root_joint = {"planar": pin.JointModelPlanar(), "free-flyer": pin.JointModelFreeFlyer(),
                  "translation": pin.JointModelTranslation()}[root]
    parent = model.addJoint(0, root_joint, pin.SE3.Identity(), "root")
    for name, joint in [("rz", pin.JointModelRZ()), ("spherical", pin.JointModelSpherical()),
                        ("unaligned", pin.JointModelRevoluteUnaligned(0.3, -0.5, 0.8)),
                        ("unbounded", pin.JointModelRUBY()), ("slide", pin.JointModelPrismaticUnaligned(0.0, 0.6, 0.8)),
                        ("rx", pin.JointModelRX())]:
        parent = model.addJoint(parent, joint, placement(), name)
    return model


def _shapes(model, rng):
    """A sphere's row on every joint (random pose and bounding centre), one obstacle on the world."""
    table = np.zeros((model.njoints, ROW))
    for s in range(model.njoints):
        table[s, KIND], table[s, JOINT] = SPHERE, s
        table[s, ROTATION] = pin.exp3(rng.normal(size=3)).ravel()
        table[s, TRANSLATION], table[s, BOUND_CENTER] = rng.uniform(-0.2, 0.2, 3), rng.uniform(-0.1, 0.1, 3)
        table[s, BOUND_RADIUS] = rng.uniform(0.01, 0.1)
    pairs = [(s, 0, 0) for s in range(1, model.njoints)] + [(1, 4, 0), (2, 7, 0), (3, 5, 0)]
    return table, np.array(pairs, dtype=np.int64)


@pytest.mark.parametrize("root", ["planar", "free-flyer", "translation"])
def test_every_joint_kind_the_bound_knows_is_bounded_at_every_configuration(root, rng):
    model = _chain(root)
    table, pairs = _shapes(model, rng)
    bounds = lever_bounds(model, table, pairs, _support(model))
    slide = model.getJointId("slide")
    after_slide = np.array([int(table[a, JOINT]) >= slide or int(table[b, JOINT]) >= slide for a, b, _ in pairs])
    # a rotation before the prismatic joint cannot bound a shape after it: inf; everything else finite
    rotational = np.arange({"planar": 2, "free-flyer": 3, "translation": 3}[root], model.joints[slide].idx_v)
    assert np.all(np.isinf(bounds[np.ix_(after_slide & (pairs[:, 1] == 0), rotational)]))
    assert np.all(np.isfinite(bounds[~after_slide]))
    finite = np.isfinite(bounds)
    for _ in range(60):
        q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        q = pin.normalize(model, q)
        levers = _levers_at(model, table, pairs, q)
        moving = ~np.isnan(levers)
        np.testing.assert_array_equal(bounds[~moving], 0.0)
        checked = moving & finite
        assert np.all(levers[checked] <= bounds[checked] * (1.0 + 1e-12)), np.max(levers[checked] / bounds[checked])


def test_the_kernel_forms_the_pairs_reach_again_when_the_speed_bound_changes():
    ee = YOUBOT.frame_pose(YOUBOT.neutral(), "ee")[:3, 3]
    data = wbc.CollisionAvoidance([wbc.Sphere(ee + (0.1, 0.0, 0.0), 0.05)]).bind(YOUBOT)
    kin = Kinematics(YOUBOT)
    kin.update(YOUBOT.neutral())
    n, nv = data.n_inequalities, YOUBOT.nv
    rows = ConstraintRows(np.zeros(nv), np.zeros(nv), np.zeros((n, nv)), np.zeros(n), np.zeros((0, nv)), np.zeros(0))
    data.write_static(rows)
    assert np.all(np.isnan(data._reach))  # not yet formed
    for bound in (np.inf, 1.0, 2.5):
        data._unbounded[:] = bound * np.linspace(1.0, 2.0, nv)  # the speed bound of a data without a controller
        data.compute(kin, 0.01, rows)
        _, _, arguments, _ = data._call
        speed, levers, reach = arguments[16], arguments[18], arguments[19]
        assert speed is data._unbounded and reach is data._reach
        np.testing.assert_array_equal(reach[:nv], speed)
        with np.errstate(invalid="ignore"):  # (0 inf: a coordinate that does not move the pair adds 0)
            expected = np.where(levers > 0.0, levers * speed, 0.0).sum(axis=1)
        np.testing.assert_allclose(reach[nv:], expected, rtol=1e-8)
