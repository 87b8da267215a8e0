"""Issue 24 §2 on the compiled path: a youBot whose platform (a box) starts inside a crate (a
wbc.Box: box-box overlap, the separating-axis kernel) or inside the margin is pushed out, never
frozen, with the rows an op of the native tick program -- on the shipped mecanum base (a crate in
front and one beside it) and on the same youBot declared a differential drive (a crate in front and
one behind: a unicycle escapes along its heading only). The oracle is coal through Pinocchio on the
URDF's raw shapes (tests/test_collision_distances.py's Oracle), independent of the kernels."""

import math
import shutil

import numpy as np
import pinocchio as pin
import pytest

import wbc
from test_collision_distances import Oracle
from wbc.collision import RobotGeometry
from wbc.collision.avoidance import CollisionAvoidanceData
from wbc.model.robot import model_path

MIN_DISTANCE = 0.02  # CollisionAvoidance's default
#: the damper holds d >= min_distance to first order; a tick's second-order term at these speeds
#: (base <= 0.8 m/s, dt = 0.01) costs far less than this [m]
TOLERANCE = 2e-3
DT = 0.01
#: ticks within which the margin is reached: from 2 cm into the crate to the 2 cm margin is 4 cm,
#: 5 ticks at the base's 0.8 m/s, then the damper halves the rest every tick (gain 0.5): ~10 ticks
REACHED_WITHIN = 30
#: the platform box: 0.58 x 0.38 x 0.1 m, its top face at z = 0 of base_link
HALF_LENGTH, HALF_WIDTH = 0.29, 0.19

UNICYCLE_TOML = """name = "youbot_unicycle"
urdf = "youbot.urdf"
end_effector = "ee"
[base]
kind = "unicycle"
joints = ["base_x", "base_y", "base_yaw"]
max_linear_speed = 0.8
max_yaw_rate = 1.0
[base.wheels]
radius = 0.0475
half_track = 0.15
max_speed = 16.842105263157894
"""


@pytest.fixture(scope="module")
def robots(tmp_path_factory):
    """The shipped youBot (mecanum) and its URDF with a sidecar declaring a differential drive."""
    folder = tmp_path_factory.mktemp("youbot_unicycle")
    shutil.copy(model_path("youbot", "urdf"), folder / "youbot.urdf")
    (folder / "youbot.toml").write_text(UNICYCLE_TOML)
    unicycle = wbc.load_robot(folder / "youbot.urdf")
    assert unicycle.base.is_nonholonomic
    return {"mecanum": wbc.load_robot("youbot"), "unicycle": unicycle}


def _crate(side, overlap):
    """A 0.2 x 0.2 x 0.08 m crate at the platform's height whose near face is ``overlap`` [m] inside
    the platform's face on ``side`` (a negative overlap: that far outside it); at the ``"corner"``,
    yawed 45 degrees, its face ``overlap`` into the platform's front left corner (the separating
    axis the crate's face normal, not one of the platform's)."""
    centre, pose = np.array([0.0, 0.0, -0.06]), np.eye(4)
    if side == "corner":
        normal = np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
        centre += (HALF_LENGTH, HALF_WIDTH, 0.0) + (0.1 - overlap) * normal
        pose[:3, :3] = pin.utils.rpyToMatrix(0.0, 0.0, math.pi / 4)
    else:
        reach, axis = {"front": (HALF_LENGTH, 0), "behind": (-HALF_LENGTH, 0), "beside": (HALF_WIDTH, 1)}[side]
        centre[axis] = math.copysign(abs(reach) + 0.1 - overlap, reach)
    pose[:3, 3] = centre
    return wbc.Box(pose, (0.2, 0.2, 0.08))


def _closest(oracle, excluded, q):
    """coal's smallest signed distance over the pairs the constraint covers."""
    return min(d for key, d in oracle.distances(q).items() if key not in excluded)


CASES = [("mecanum", "front"), ("mecanum", "beside"), ("mecanum", "corner"), ("unicycle", "front"),
         ("unicycle", "behind"), ("unicycle", "corner")]


@pytest.mark.parametrize("overlap", [0.02, -0.01], ids=["2 cm in", "1 cm out"])
@pytest.mark.parametrize(("base", "side"), CASES, ids=[f"{b} {s}" for b, s in CASES])
def test_the_platform_is_pushed_out_of_a_crate(robots, base, side, overlap):
    """From the first tick on, coal's distance d of the closest pair grows strictly every tick
    until d >= MIN_DISTANCE - TOLERANCE (within REACHED_WITHIN ticks), then stays there; every
    command is finite, within the speed limits (and without sideways slip on the differential
    drive); no tick falls back to the zero command. 2 cm in, the damper asks for an escape of
    gain (d_min - d) / dt = 2 m/s, above the base's 0.8 m/s: those first ticks may be the elastic
    fallback's (the rows yield to the speed limit, not to a freeze), a leading run only; 1 cm out
    it asks 0.5 m/s: every tick optimal."""
    robot = robots[base]
    neutral = robot.neutral()
    crate = _crate(side, overlap)
    excluded = {frozenset((e.link_a, e.link_b)) for e in RobotGeometry(robot).excluded}
    oracle = Oracle(robot, [crate])
    start = _closest(oracle, excluded, neutral)
    assert start == pytest.approx(-overlap, abs=1e-9)  # the platform's face against the crate's
    hold = wbc.PostureTask(cost=1e-2, gain=0.5, target=neutral)  # pulls back into the crate
    avoidance = wbc.CollisionAvoidance([crate], min_distance=MIN_DISTANCE)
    constraints = [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), avoidance]
    if robot.base.is_nonholonomic:
        constraints.append(wbc.NonholonomicBase())
    controller = wbc.Controller(robot, [hold], constraints)
    # the rows are the compiled op of the tick program, not CollisionAvoidanceData.compute; on the
    # holonomic base the whole tick is one native call (a nonholonomic one maps the inputs after it)
    assert controller._stepper is not None or robot.base.is_nonholonomic
    assert not any(isinstance(data, CollisionAvoidanceData) for data, _ in controller._python_constraints)
    limit = robot.velocity_limit
    q, closest, outcomes = neutral, [], []
    for _ in range(60):
        v = controller.step(q)
        assert np.all(np.isfinite(v))
        # (xdot, ydot) in the world frame, the linear speed limit along the platform's axes
        cos, sin = math.cos(q[2]), math.sin(q[2])
        along, across = cos * v[0] + sin * v[1], -sin * v[0] + cos * v[1]
        assert np.all(np.abs([along, across, *v[2:]]) <= limit + 1e-9)
        if robot.base.is_nonholonomic:
            assert across == pytest.approx(0.0, abs=1e-9)  # no sideways slip
        outcomes.append(controller.last.outcome)
        q = robot.integrate(q, v, DT)
        closest.append(_closest(oracle, excluded, q))
    closest = np.array(closest)
    assert closest[0] > start  # moving out from the first tick, not frozen
    reached = int(np.flatnonzero(closest >= MIN_DISTANCE - TOLERANCE)[0])
    assert reached < REACHED_WITHIN
    assert np.all(np.diff(closest[:reached + 1]) > 0.0)  # pushed out every tick until the margin
    assert np.all(closest[reached:] >= MIN_DISTANCE - TOLERANCE)
    assert set(outcomes) <= {wbc.Outcome.OPTIMAL, wbc.Outcome.ELASTIC}  # never the zero command
    fallbacks = outcomes.count(wbc.Outcome.ELASTIC)
    assert wbc.Outcome.ELASTIC not in outcomes[fallbacks:]  # a leading run of elastic ticks
    if overlap < 0:
        assert fallbacks == 0

