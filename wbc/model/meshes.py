"""Where a URDF's ``package://`` mesh paths are found (the 3-D view's visual shapes and the
collision shapes read the same meshes)."""

from __future__ import annotations

from pathlib import Path


def package_dirs(urdf: str | Path) -> list[str]:
    """Where ``package://NAME/...`` mesh paths of ``urdf`` are looked for: the URDF's folder and
    every folder above it (a ROS install tree or a Python package's data, e.g.
    ``.../share/example-robot-data/robots/tiago_description/robots/tiago.urdf`` names meshes as
    ``package://example-robot-data/robots/...``, found in ``.../share``); Pinocchio adds
    ``ROS_PACKAGE_PATH`` itself."""
    folder = Path(urdf).resolve().parent
    return [str(folder), *(str(parent) for parent in folder.parents)]
