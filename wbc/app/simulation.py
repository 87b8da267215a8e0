"""MuJoCo in the loop: the controller commands velocity servos of the robot's MJCF.

Each control tick of length ``dt``: read the joint positions (optionally with Gaussian
noise), compute ``v``, send it to the velocity actuators (optionally one tick late, as
a real bus would), and integrate the physics for ``dt`` with the MJCF's own timestep.
The MJCF must list its joints in the order of the robot's coordinates and have one
velocity actuator per coordinate, in the same order (``models/youbot/youbot.xml``).

Contacts are off (``mjDSBL_CONTACT``, whatever the MJCF says): the loop checks the controller,
so a distance it keeps (``wbc.CollisionAvoidance``) is its own doing, never the simulator
pushing a link back, and a distance it loses shows as a penetration, not as a contact force.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import ModelError
from ..core.validation import as_positive
from ..model.robot import Robot, model_path


class MujocoSimulation:
    """A MuJoCo model of ``robot`` driven through velocity servos.

    Args:
        robot: the wbc robot (its shipped model must have an MJCF).
        dt: control period [s] (a multiple of the MJCF timestep).
        noise: standard deviation of the position measurement noise [rad or m].
        delay: ticks between computing a command and applying it (0 or 1).
        seed: noise generator seed.
    """

    def __init__(self, robot: Robot, dt: float, noise: float = 0.0, delay: int = 0, seed: int = 0) -> None:
        import mujoco

        self._mujoco = mujoco
        self.robot = robot
        try:
            path = model_path(robot.name, "mjcf")
        except ModelError as exc:
            raise ModelError(f"robot '{robot.name}' ships no MJCF for simulation") from exc
        self.model = mujoco.MjModel.from_xml_path(str(path))
        self.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        self.data = mujoco.MjData(self.model)
        names = [self.model.joint(i).name for i in range(self.model.njnt)]
        actuated = [self.model.joint(self.model.actuator(i).trnid[0]).name for i in range(self.model.nu)]
        if names != robot.joint_names or actuated != robot.joint_names or self.model.nq != robot.nq:
            raise ModelError(f"{path}: joints {names} / actuators {actuated} do not match {robot.joint_names}")
        self.dt = as_positive(dt, "dt")
        self.substeps = int(round(self.dt / self.model.opt.timestep))
        if self.substeps < 1 or abs(self.substeps * self.model.opt.timestep - self.dt) > 1e-9:
            raise ModelError(f"dt = {dt} is not a multiple of the MJCF timestep {self.model.opt.timestep}")
        if delay not in (0, 1):
            raise ValueError("delay must be 0 or 1 tick")
        self.noise, self.delay = float(noise), delay
        self._rng = np.random.default_rng(seed)
        self._pending = np.zeros(robot.nv)

    def reset(self, q: np.ndarray) -> None:
        """Put the robot at rest in configuration ``q``."""
        self._mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = q
        self._pending[:] = 0.0
        self._mujoco.mj_forward(self.model, self.data)

    @property
    def q(self) -> np.ndarray:
        """True joint positions (a copy)."""
        return self.data.qpos.copy()

    def measure(self) -> np.ndarray:
        """Joint positions as a sensor reports them (with noise)."""
        q = self.data.qpos.copy()
        if self.noise > 0.0:
            q += self._rng.normal(0.0, self.noise, q.shape)
        return q

    def apply(self, v: np.ndarray) -> None:
        """Send a velocity command; with ``delay=1`` it reaches the servos one tick later."""
        if self.delay:
            self.data.ctrl[:], self._pending[:] = self._pending, v
        else:
            self.data.ctrl[:] = v

    def advance(self) -> None:
        """Integrate the physics over one control period."""
        self._mujoco.mj_step(self.model, self.data, nstep=self.substeps)
