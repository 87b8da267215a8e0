"""wbc.runtime.native_entry.fits_signature: the guard before a compiled entry is called without
numba's type check (which would read an array of another dimension or layout wrongly), and the
collision kernel called through it gives the dispatcher's rows."""

import numpy as np
import pytest

import wbc
from wbc.collision import kernels
from wbc.constraints.constraint import ConstraintRows
from wbc.model.kinematics import Kinematics
from wbc.runtime.native_entry import fits_signature

YOUBOT = wbc.load_robot("youbot")
NEUTRAL = YOUBOT.neutral()


def _bound_data():
    """A CollisionAvoidanceData after one tick near a sphere and a box, and its rows."""
    ee = YOUBOT.frame_pose(NEUTRAL, "ee")[:3, 3]
    box = np.eye(4)
    box[:3, 3] = ee + (0.0, 0.15, 0.0)
    data = wbc.CollisionAvoidance([wbc.Sphere(ee + (0.1, 0.0, 0.0), 0.05), wbc.Box(box, (0.1, 0.1, 0.1))]).bind(YOUBOT)
    n, nv = data.n_inequalities, YOUBOT.nv
    kin = Kinematics(YOUBOT)
    kin.update(NEUTRAL)
    rows = ConstraintRows(np.zeros(nv), np.zeros(nv), np.zeros((n, nv)), np.zeros(n), np.zeros((0, nv)), np.zeros(0))
    data.write_static(rows)  # (as wbc.qp.layout does when a controller is built)
    data.compute(kin, 0.01, rows)
    return data, kin, rows


def test_the_collision_kernel_arguments_fit_and_its_entry_gives_the_dispatchers_rows():
    data, kin, rows = _bound_data()
    _, _, arguments, bound = data._call
    assert fits_signature(kernels.avoidance_rows, arguments)
    assert bound.func is not kernels.avoidance_rows  # the compiled entry, not the dispatcher
    assert data.pairs.count >= 2 and data.corners >= 0
    G, h = rows.G.copy(), rows.h.copy()
    written = data.pairs.count + data.corners  # (the rows after them are inert, and the kernel leaves them)
    assert np.all(G[written:] == 0.0) and np.all(h[written:] == kernels.INERT)
    rows.G[:written], rows.h[:written] = 0.0, 0.0
    assert kernels.avoidance_rows(*arguments) == (data.pairs.count, data.corners)
    np.testing.assert_array_equal(rows.G, G)
    np.testing.assert_array_equal(rows.h, h)


@pytest.mark.parametrize("fault", ["transposed", "int64", "1-D", "not an array", "one too few"])
def test_arguments_that_do_not_fit_the_signature_are_refused(fault):
    data, _, _ = _bound_data()
    arguments = list(data._call[2])
    G = arguments[11]
    if fault == "transposed":  # float64[:, ::1] given a Fortran-ordered array of the same shape
        arguments[11] = np.asfortranarray(G)
    elif fault == "int64":
        arguments[11] = G.astype(np.int64)
    elif fault == "1-D":
        arguments[11] = G.ravel()
    elif fault == "not an array":
        arguments[11] = G.tolist()
    else:
        arguments.pop()
    assert not fits_signature(kernels.avoidance_rows, tuple(arguments))


def test_a_function_without_exactly_one_signature_does_not_fit():
    assert not fits_signature(lambda x: x, (np.zeros(1),))


def test_a_tick_with_overlapping_boxes_gets_coals_distance_without_coal(monkeypatch):
    """A box obstacle overlapping the youBot's platform box: the kernel's bound entry measures the
    pair itself (nothing handed to coal) and the tick's entry is coal's distance (oracle: the
    platform's URDF box and the obstacle as coal shapes, measured here)."""
    from test_collision_distances import Oracle

    robot = YOUBOT
    kin = Kinematics(robot)
    kin.update(NEUTRAL)
    geometry = wbc.collision.RobotGeometry(robot)
    platform = next(i for i, link in enumerate(geometry.links) if geometry.table[i, 0] == 3)  # the box (layout.BOX)
    pose = np.eye(4)
    pose[:3, 3] = robot.frame_pose(NEUTRAL, geometry.links[platform])[:3, 3] + (0.25, 0.0, 0.0)
    box = wbc.Box(pose, (0.2, 0.2, 0.2))  # its centre inside the platform's edge: the boxes overlap
    data = wbc.CollisionAvoidance([box], self_collision=False).bind(robot)
    n, nv = data.n_inequalities, robot.nv
    rows = ConstraintRows(np.zeros(nv), np.zeros(nv), np.zeros((n, nv)), np.zeros(n), np.zeros((0, nv)), np.zeros(0))
    handed_over = []
    finish = data.distances.finish_with_coal
    monkeypatch.setattr(data.distances, "finish_with_coal", lambda *a: handed_over.append(a[1]) or finish(*a))
    data.compute(kin, 0.01, rows)
    assert not handed_over  # the kernel measured every pair
    labels = data.active_labels()
    entry = labels.index(f"{geometry.links[platform]}↔box0")
    expected = Oracle(robot, [box]).distances(NEUTRAL)[frozenset((geometry.links[platform], "obstacle0"))]
    assert expected < 0.0  # overlapping
    assert data.pairs.distance[entry] == pytest.approx(expected, abs=1e-6)
    assert data._call[3].func is not kernels.avoidance_rows  # through the compiled entry
