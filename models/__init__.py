"""Robot descriptions shipped with wbc (installed as the ``wbc.models`` package).

Each robot lives in its own folder ``<name>/`` with ``<name>.urdf`` (kinematics
for Pinocchio), ``<name>.xml`` (MJCF for MuJoCo, same kinematics) and
``<name>.toml`` (what a URDF cannot say: base kind, unbounded coordinates,
wheel geometry, document references).
"""
