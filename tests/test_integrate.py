"""``Robot.integrate``: ``q + v dt`` in one compiled call where every coordinate is a vector
space, the base's own integration elsewhere; the same answers and the same refusals either way.
Oracle: ``pinocchio.integrate(model, q, v dt)``."""

import copy
import dataclasses
import warnings

import numpy as np
import pinocchio as pin
import pytest

import wbc

CONTINUOUS = """<robot name="wheel_arm">
  <link name="world"/><link name="a"/><link name="b"/><link name="tip"/>
  <joint name="spin" type="continuous"><parent link="world"/><child link="a"/><axis xyz="0 0 1"/>
    <limit effort="1" velocity="2"/></joint>
  <joint name="lift" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
    <origin xyz="0.1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="tool" type="fixed"><parent link="b"/><child link="tip"/><origin xyz="0.2 0 0"/></joint>
</robot>"""


class _CountingIntegrate:
    """``pinocchio.integrate``, counting its calls."""

    def __init__(self, original):
        self.original, self.calls = original, 0

    def __call__(self, *args):
        self.calls += 1
        return self.original(*args)


@pytest.fixture
def counting(monkeypatch):
    counter = _CountingIntegrate(pin.integrate)
    monkeypatch.setattr(pin, "integrate", counter)
    return counter


@pytest.mark.parametrize("name", wbc.model.robot.shipped_models())
def test_vector_space_robots_integrate_without_pinocchio_and_agree_with_it(name, rng, counting):
    """Every shipped robot (1-DOF revolute and prismatic joints, planar bases as x, y, yaw joints):
    Pinocchio's answer to the last bit, and no Pinocchio call on the control loop's path."""
    robot = wbc.load_robot(name)
    for _ in range(20):
        q, v, dt = robot.random_configuration(rng), rng.normal(size=robot.nv) * 3.0, float(rng.uniform(1e-4, 0.5))
        reached = robot.integrate(q, v, dt)
        assert counting.calls == 0
        np.testing.assert_array_equal(reached, counting.original(robot.model, q, v * dt))
        assert reached is not q and reached is not v


def test_a_continuous_joint_integrates_on_its_circle(tmp_path, rng, counting):
    """nq = 3, nv = 2: (cos, sin) of the wheel rotate; Pinocchio integrates (not q + v dt)."""
    path = tmp_path / "wheel_arm.urdf"
    path.write_text(CONTINUOUS)
    robot = wbc.load_robot(path)
    assert (robot.nq, robot.nv) == (3, 2)
    q = pin.neutral(robot.model)
    v, dt = np.array([0.7, -0.2]), 0.5
    reached = robot.integrate(q, v, dt)
    assert counting.calls == 1
    np.testing.assert_allclose(reached, [np.cos(0.35), np.sin(0.35), -0.1], rtol=0, atol=1e-15)


def test_a_base_with_its_own_integration_keeps_it(youbot, rng):
    """A base class that overrides ``integrate`` (a floating base, a base that integrates in its
    own frame) is called even when every joint is a vector space."""

    class SlowBase(type(youbot.base)):
        def integrate(self, model, q, v, dt):
            return super().integrate(model, q, v, dt / 2)

    base = copy.copy(youbot.base)
    object.__setattr__(base, "__class__", SlowBase)  # a frozen dataclass
    robot = dataclasses.replace(youbot, base=base)
    q, v = robot.random_configuration(rng), rng.normal(size=robot.nv)
    np.testing.assert_allclose(robot.integrate(q, v, 0.2), q + 0.1 * v, rtol=0, atol=1e-15)


@pytest.mark.parametrize("where", ["q", "v"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_non_finite_q_or_v_is_refused_naming_it(youbot, where, bad):
    q, v = youbot.neutral(), np.zeros(8)
    (q if where == "q" else v)[3] = bad
    with pytest.raises(wbc.InvalidInputError, match=f"^{where} contains NaN or inf"):
        youbot.integrate(q, v, 0.01)


@pytest.mark.parametrize("robot_kind", ["vector space", "continuous joint"])
def test_a_step_that_overflows_is_refused_without_a_warning(youbot, tmp_path, robot_kind):
    """Finite q, v and dt whose ``q + v dt`` overflows: refused (it returned inf entries, with a
    numpy warning) on the compiled path and on Pinocchio's; a step just inside range is taken."""
    if robot_kind == "vector space":
        robot = youbot
    else:
        (tmp_path / "wheel_arm.urdf").write_text(CONTINUOUS)
        robot = wbc.load_robot(tmp_path / "wheel_arm.urdf")
    q = pin.neutral(robot.model)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(wbc.InvalidInputError, match=r"q \+ v dt overflows \(dt = 10.0, largest \|v\| = 1e\+308\)"):
            robot.integrate(q, np.full(robot.nv, 1e308), 10.0)
        reached = robot.integrate(q, np.full(robot.nv, 1e300), 10.0)
    assert np.all(np.isfinite(reached)) and np.abs(reached).max() >= 1e301


def test_other_inputs_take_the_checked_path(youbot, rng):
    """Lists, other dtypes, strided views and an int dt give Pinocchio's answer; wrong sizes,
    a bool or non-positive dt are refused."""
    q, v = youbot.random_configuration(rng), rng.normal(size=8)
    expected = pin.integrate(youbot.model, q, v * 0.01)
    np.testing.assert_array_equal(youbot.integrate(q.tolist(), v.tolist(), 0.01), expected)
    np.testing.assert_allclose(youbot.integrate(q.astype(np.float32), v, 0.01), expected, atol=1e-6)
    wide = np.zeros((8, 2))
    wide[:, 0] = v
    np.testing.assert_array_equal(youbot.integrate(q, wide[:, 0], 0.01), expected)
    np.testing.assert_array_equal(youbot.integrate(q, v, 1), pin.integrate(youbot.model, q, v))
    for bad_q, bad_v in ((q[:7], v), (q, v[:7]), (np.append(q, 0.0), np.append(v, 0.0))):
        with pytest.raises(wbc.InvalidInputError, match="shape"):
            youbot.integrate(bad_q, bad_v, 0.01)
    for dt in (True, 0.0, -0.01):
        with pytest.raises(wbc.InvalidInputError, match="dt"):
            youbot.integrate(q, v, dt)


# ----------------------------------------------------- FrameTask.set_target(pose)
def test_set_target_checks_shape_and_pose_in_its_one_compiled_call():
    """The fast path's kernel takes any 2-D float64 array: it refuses every shape but 4 x 4
    (it must never read past a smaller array) and a non-rigid pose, keeping the previous target;
    a strided view, float32 or a nested list of a valid pose is the pose."""
    task = wbc.FrameTask("ee")
    pose = np.eye(4)
    pose[:3, :3] = pin.rpy.rpyToMatrix(0.3, -0.2, 1.1)
    pose[:3, 3] = [0.4, -0.1, 0.7]
    task.set_target(pose)
    for bad in (np.eye(3), np.eye(5), np.zeros((4, 3)), np.eye(4)[:, :, None], np.eye(4).ravel()):
        with pytest.raises(wbc.InvalidInputError, match="shape"):
            task.set_target(bad)
    for bad in (np.diag([1.0, 1.0, -1.0, 1.0]), np.where(np.eye(4) > 0, np.nan, 0.0), 2 * np.eye(4)):
        with pytest.raises(wbc.InvalidInputError):
            task.set_target(bad)
    np.testing.assert_array_equal(task.target, pose)
    wide = np.zeros((4, 8))
    wide[:, ::2] = pose
    for same in (wide[:, ::2], np.asfortranarray(pose), pose.tolist()):
        task.set_target(np.eye(4))
        task.set_target(same)
        np.testing.assert_array_equal(task.target, pose)
    task.set_target(pose.astype(np.float32))
    np.testing.assert_allclose(task.target, pose, atol=1e-7)


def test_a_read_only_pose_or_twist_is_a_target():
    """Regression: a read-only array (e.g. a pose kept in a frozen record) reached the compiled
    setter, whose signature takes writable arrays: a raw numba TypeError instead of the target."""
    task = wbc.FrameTask("ee")
    pose = np.eye(4)
    pose[:3, 3] = [0.3, 0.2, 0.1]
    twist = np.arange(6.0)
    pose.flags.writeable = twist.flags.writeable = False
    task.set_target(pose)
    np.testing.assert_array_equal(task.target, pose)
    task.set_target(pose, twist=twist)
    np.testing.assert_array_equal(task._feedforward, twist)


class _ArrayLike:
    """Not an ndarray, but with an ndarray's dtype and ndim (e.g. another library's array)."""

    def __init__(self, array: np.ndarray) -> None:
        self._array, self.dtype, self.ndim = array, array.dtype, array.ndim

    def __array__(self, dtype=None, copy=None):
        return self._array if dtype is None else self._array.astype(dtype)


class _Subclass(np.ndarray):
    pass


def test_set_target_takes_array_likes_subclasses_and_other_byte_orders():
    """The fast path calls the compiled setter without numba's type check, after checking that
    the pose is a 2-D float64 array itself: anything else is converted by the checked path."""
    task = wbc.FrameTask("ee")
    pose = np.eye(4)
    pose[:3, :3] = pin.rpy.rpyToMatrix(-0.4, 0.1, 0.9)
    pose[:3, 3] = [0.2, 0.5, -0.3]
    for same in (_ArrayLike(pose), pose.view(_Subclass), pose.astype(">f8"), pose.T.copy().T):
        task.set_target(np.eye(4))
        task.set_target(same)
        np.testing.assert_array_equal(task.target, pose)
    with pytest.raises(wbc.InvalidInputError, match="shape"):
        task.set_target(_ArrayLike(np.eye(3)))


def test_integrate_takes_array_likes_read_only_and_byte_swapped_vectors(youbot, rng):
    """The vector-space fast path calls the compiled q + v dt without numba's type check, after
    checking that q and v are 1-D float64 arrays: anything else is converted by the checked path,
    and a 2-D array of the right size is refused as before."""
    q, v = youbot.random_configuration(rng), rng.normal(size=8)
    expected = pin.integrate(youbot.model, q, v * 0.01)
    read_only = q.copy()
    read_only.flags.writeable = False
    for same_q, same_v in ((read_only, v), (_ArrayLike(q), _ArrayLike(v)), (q.view(_Subclass), v.astype(">f8"))):
        np.testing.assert_array_equal(youbot.integrate(same_q, same_v, 0.01), expected)
    for bad_q, bad_v in ((q[None, :], v), (q, v[:, None]), (_ArrayLike(q[:7]), v)):
        with pytest.raises(wbc.InvalidInputError, match="shape"):
            youbot.integrate(bad_q, bad_v, 0.01)
