"""A base kind written in this file only (docs/extending.md, "A new base kind"): a crab drive,
whose wheels roll along the base's y axis, driven in closed loop by the shipped constraints
(JointVelocityLimits, NonholonomicBase, WheelSpeedLimits) and the reduced form. Its rows,
input map and wheel speeds are checked against formulas written out here."""

from __future__ import annotations

import copy
import math
import pickle
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest

import wbc
from conftest import require
from wbc.constraints.heading_rows import HeadingRows
from wbc.model.bases import BaseKind, PlanarBase, TwistRows

RADIUS, HALF_TRACK, WHEEL_LIMIT = 0.05, 0.2, 10.0  # [m], [m], [rad/s]
SPEED, YAW_RATE = 0.3, 0.8  # [m/s], [rad/s]


@dataclass(frozen=True)
class CrabWheels:
    """Two wheels on the base's x axis at +-b (front, back), rolling along the base's y axis:
    ``u = ((v_y + b omega) / r, (v_y - b omega) / r)``."""

    radius: float
    half_track: float
    max_speed: float = math.inf

    def inverse_matrix(self) -> np.ndarray:
        b = self.half_track
        return np.array([[0.0, 1.0, b], [0.0, 1.0, -b]]) / self.radius


@dataclass(frozen=True)
class CrabDrive(PlanarBase):
    """The new kind, all of it: drives sideways, never slips along its x axis, one speed bound
    on ``|v_y|``."""

    kind: BaseKind = BaseKind.CUSTOM
    no_slip = ((1.0, 0.0, 0.0),)  # v_x = 0
    no_slip_labels = ("no forward slip",)
    input_twists = ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0))  # u = (v_y, omega)

    @property
    def name(self) -> str:
        return "crab"

    def speed_rows(self) -> TwistRows:
        return TwistRows(((0.0, 1.0, 0.0), (0.0, -1.0, 0.0)), self.max_linear_speed,
                         ("base v_y upper", "base v_y lower"))


@pytest.fixture(scope="module")
def crab() -> wbc.Robot:
    youbot = wbc.load_robot("youbot")
    base = CrabDrive(indices=youbot.base.indices, max_linear_speed=SPEED, max_yaw_rate=YAW_RATE,
                     wheels=CrabWheels(RADIUS, HALF_TRACK, WHEEL_LIMIT))
    return wbc.Robot("crab", youbot.model, base=base, end_effector=youbot.end_effector)


def base_frame(q: np.ndarray, v: np.ndarray) -> tuple[float, float]:
    """(v_x, v_y) of the world base rates, written out: R(heading)^T (xdot, ydot)."""
    c, s = math.cos(q[2]), math.sin(q[2])
    return c * v[0] + s * v[1], -s * v[0] + c * v[1]


def test_the_robot_asks_the_new_kind(crab, rng):
    assert crab.base.is_mobile and crab.base.is_nonholonomic and crab.nu == crab.nv - 1
    assert repr(crab) == "Robot('crab', nq=8, nv=8, base=crab)"
    assert crab.velocity_limit[2] == YAW_RATE and np.isinf(crab.lower[:3]).all()
    for _ in range(20):
        q = crab.random_configuration(rng)
        c, s = math.cos(q[2]), math.sin(q[2])
        expected = np.zeros((8, 7))
        expected[:3, 0] = (-s, c, 0.0)  # v_y drives along the base's y axis in the world
        expected[2, 1] = 1.0
        expected[3:, 2:] = np.eye(5)
        np.testing.assert_allclose(crab.input_map(q), expected, atol=1e-15)
        u = rng.uniform(-1, 1, 7)
        v = expected @ u
        np.testing.assert_allclose(crab.base_twist(q, v), [0.0, u[0], u[1]], atol=1e-14)
        np.testing.assert_allclose(crab.wheel_speeds(q, v), [(u[0] + HALF_TRACK * u[1]) / RADIUS,
                                                             (u[0] - HALF_TRACK * u[1]) / RADIUS], atol=1e-12)


def test_twist_rows_become_heading_rows(rng):
    """HeadingRows.of_twist: rows M t on the base-frame twist, written as rows on v, equal
    M @ B(heading) with B written out."""
    matrix = rng.uniform(-1, 1, (5, 3))
    rows = HeadingRows.of_twist(TwistRows(matrix, 1.0, tuple("abcde")), (3, 1, 0))
    for heading in rng.uniform(-4, 4, 10):
        q = np.array([heading, 0.0, 0.0, 0.0])
        G = np.zeros((5, 4))
        rows.write_heading_column(G)
        rows.write(q, G)
        c, s = math.cos(heading), math.sin(heading)
        B = np.zeros((3, 4))  # t = B v with v = (heading rate, y rate, -, x rate)
        B[0, 3], B[0, 1], B[1, 3], B[1, 1], B[2, 0] = c, s, -s, c, 1.0
        np.testing.assert_allclose(G, matrix @ B, atol=1e-14)


def test_the_new_kind_drives_in_closed_loop_with_the_shipped_constraints(crab):
    """Reach a point 1.5 m ahead, 1 m to the side: the crab cannot drive along its x axis, so
    it steers (the arm points along the base's y axis: the heading rate moves the tool along
    x) and drives sideways; every tick the no-slip row, the |v_y| rows, the yaw rate and the
    wheel limit hold, and the reduced form agrees."""
    reach = wbc.PositionTask(crab.end_effector, cost=1.0, gain=0.1, max_speed=0.4)
    q = np.array([0.0, 0.0, 0.0, 1.5, 0.5, 1.0, 1.2, 0.0])
    target = crab.frame_pose(q, crab.end_effector)[:3, 3] + [1.5, 1.0, 0.0]
    reach.set_target(target)
    tasks = [reach, wbc.PostureTask(1e-4, target=q)]
    constraints = [wbc.NonholonomicBase(), wbc.JointPositionLimits(), wbc.JointVelocityLimits(),
                   wbc.WheelSpeedLimits()]
    controller = wbc.Controller(crab, tasks, constraints)
    reduced = wbc.Controller(crab, tasks, constraints, reduced=True)
    headings = []
    for k in range(2000):
        v = controller.step(q)
        assert controller.last.status == "optimal"
        if k % 100 == 0:
            np.testing.assert_allclose(reduced.step(q), v, rtol=0, atol=1e-8)
        v_x, v_y = base_frame(q, v)
        assert abs(v_x) <= 1e-9, "no slip along the base's x axis"
        assert abs(v_y) <= SPEED + 1e-9 and abs(v[2]) <= YAW_RATE + 1e-9
        front, back = (v_y + HALF_TRACK * v[2]) / RADIUS, (v_y - HALF_TRACK * v[2]) / RADIUS
        assert max(abs(front), abs(back)) <= WHEEL_LIMIT * (1 + 1e-9)
        headings.append(q[2])
        q = crab.integrate(q, v, controller.dt)
    assert np.ptp(headings) > 1.0, "the base turned to drive toward the target"
    assert np.linalg.norm(crab.frame_pose(q, crab.end_effector)[:3, 3] - target) < 1e-3


def test_steering_refuses_a_base_that_does_not_drive_along_its_x_axis(crab):
    """SteeringTask aligns the base's x axis with the way to go: wrong for the crab."""
    with pytest.raises(wbc.InvalidInputError, match="drives along its x axis"):
        wbc.Controller(crab, [wbc.SteeringTask()], [wbc.NonholonomicBase()])


def test_controllers_of_the_new_kind_copy_and_pickle(crab):
    reach = wbc.PositionTask(crab.end_effector, cost=1.0, gain=0.1)
    q = np.array([0.1, -0.2, 0.3, 0.0, 0.5, 1.0, 1.2, 0.0])
    reach.set_target(crab.frame_pose(q, crab.end_effector)[:3, 3] + [0.3, 0.4, 0.0])
    controller = wbc.Controller(crab, [reach], [wbc.NonholonomicBase(), wbc.JointVelocityLimits()])
    v = controller.step(q)
    for twin in (copy.deepcopy(controller), pickle.loads(pickle.dumps(controller))):
        assert isinstance(twin.robot.base, CrabDrive) and twin.robot.base == crab.base
        np.testing.assert_allclose(twin.step(q), controller.step(q), rtol=0, atol=1e-12)
    assert abs(base_frame(q, v)[0]) <= 1e-9


def test_mobile_base_by_kind_builds_the_kinds_class():
    base = wbc.MobileBase(wbc.BaseKind.UNICYCLE, indices=(0, 1, 2), max_linear_speed=0.5)
    assert type(base).__name__ == "UnicycleBase" and base.is_nonholonomic and base.name == "unicycle"
    assert base == wbc.MobileBase(kind=wbc.BaseKind.UNICYCLE, max_linear_speed=0.5)
    with pytest.raises(TypeError, match="shipped BaseKind"):
        wbc.MobileBase(BaseKind.CUSTOM)
    with pytest.raises(TypeError, match="not BaseKind.FIXED"):
        CrabDrive(BaseKind.FIXED)


class _Writer:
    """A DDS writer stand-in: keeps (linear.x, linear.y, angular.z) of every Twist written."""

    def __init__(self) -> None:
        self.written: list[tuple[float, float, float]] = []

    def write(self, message) -> None:
        self.written.append((message.linear.x, message.linear.y, message.angular.z))


def test_the_ros_node_sends_the_twist_the_new_kind_drives(crab, rng):
    """The base command keeps the crab's sideways speed (a unicycle's v_y residual is what the
    no-slip projection removes) and its speed guard reads the crab's own rows."""
    commands = require("wbc.ros.commands")
    writer = _Writer()
    participant = SimpleNamespace(writer=lambda topic, message: writer)
    config = SimpleNamespace(controllers=[], base=SimpleNamespace(stamped=False, topic="/cmd_vel", frame_id="base"))
    command_writer = commands.CommandWriter(participant, config, crab)
    q = crab.random_configuration(rng)
    u = np.array([0.2, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0])  # 0.2 m/s sideways, 0.5 rad/s
    command_writer.publish(q, crab.input_map(q) @ u)
    np.testing.assert_allclose(writer.written[-1], (0.0, 0.2, 0.5), atol=1e-12)
    too_fast = crab.input_map(q) @ np.r_[2 * SPEED, np.zeros(6)]
    assert commands.limit_ratio(crab, q, too_fast) == pytest.approx(2.0)  # |v_y| rows: twice the bound
