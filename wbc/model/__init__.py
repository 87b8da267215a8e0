"""The robot model: what the robot is and where its frames are.

* :mod:`wbc.model.robot` -- :class:`~wbc.model.robot.Robot`, loaded from a URDF (and its sidecar);
* :mod:`wbc.model.mobile_base` -- the public names of the mobile bases (conventions, :class:`MobileBase`);
* :mod:`wbc.model.bases` -- one module per kind of base behind the :class:`MobileBase` interface;
* :mod:`wbc.model.declared_base` -- base joints added to third-party models, wheels read from them;
* :mod:`wbc.model.kinematics` -- the kinematics of one tick, computed once for every item;
* :mod:`wbc.model.manipulability` -- the manipulability measure and its gradient;
* :mod:`wbc.model.shipped` -- where the shipped robot models and scenario files are.

It imports only the core and the runtime.
"""
