"""A ROS 2 node around a :class:`wbc.Controller`, speaking DDS directly (extra ``[ros]``:
``cyclonedds``; no ROS install, no ``rclpy``): ``wbc ros SCENARIO --config FILE``.

Importing :mod:`wbc` never imports this package; its modules import ``cyclonedds``.
"""
