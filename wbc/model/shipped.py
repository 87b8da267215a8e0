"""The files shipped with wbc -- robot models and scenario files -- found the same way in an
installed package and in a source tree.

Installed (from a wheel or an sdist) they are package data: ``wbc/models/<robot>/`` and
``wbc/scenarios/*.toml`` (``pyproject.toml`` maps the repository's ``models/`` and
``tasks/`` there). Run from a clone without installing it (a script or REPL started in the
clone root imports the clone's ``wbc/``), they are the clone's ``models/`` and ``tasks/``
next to the package. Nothing here depends on how, or whether, wbc was installed.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Literal

from ..core.errors import WbcError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

Kind = Literal["models", "scenarios"]

_PACKAGE = Path(__file__).resolve().parents[1]  # wbc/ (this file is wbc/model/shipped.py)
#: where each kind lives in a source tree (the installed name is the kind itself)
_SOURCE_FOLDER: dict[str, str] = {"models": "models", "scenarios": "tasks"}


def folder(kind: Kind) -> Path:
    """The folder of the shipped ``kind`` of files: the installed package data, else the
    source tree's folder. Raises :class:`~wbc.core.errors.WbcError` when neither exists (a broken
    install)."""
    installed = _PACKAGE / kind
    if installed.is_dir():
        return installed
    source = _PACKAGE.parent / _SOURCE_FOLDER[kind]
    if source.is_dir():
        return source
    raise WbcError(f"the shipped {kind} are missing (neither {installed} nor {source} exists): "
                   f"reinstall wbc (pip install --force-reinstall wbc)")


def scenario_names() -> list[str]:
    """Names of the shipped scenario files (``wbc run NAME`` runs one)."""
    return sorted(path.stem for path in folder("scenarios").glob("*.toml"))


def scenario_path(name: str) -> Path:
    """Path of the shipped scenario ``name`` (a name from :func:`scenario_names`)."""
    return folder("scenarios") / f"{name}.toml"


def scenario_description(name: str) -> str:
    """The ``description`` of the shipped scenario ``name`` (what it shows, one line)."""
    with open(scenario_path(name), "rb") as stream:
        return str(tomllib.load(stream).get("description", ""))
