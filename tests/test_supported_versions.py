"""The oldest-versions CI job (.ci/oldest) tests exactly the lower bounds pyproject.toml declares."""

import sys

from packaging.requirements import Requirement

from conftest import ROOT

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: requirements the test suite does not import, so no CI job can test a lower bound for them
OUTSIDE_THE_SUITE = {"pytest-benchmark"}  # benchmarks/test_micro.py only


def declared_requirements() -> list[Requirement]:
    """Core and optional requirements of pyproject.toml that apply here (markers evaluated)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    lines = list(project["dependencies"])
    for requirements in project["optional-dependencies"].values():
        lines += [line for line in requirements if not line.startswith("wbc[")]
    return [req for req in map(Requirement, lines) if req.marker is None or req.marker.evaluate()]


def pinned_versions() -> dict[str, str]:
    """name -> version of .ci/oldest-constraints.txt."""
    pins = {}
    for line in (ROOT / ".ci" / "oldest-constraints.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            requirement = Requirement(line)
            (specifier,) = requirement.specifier
            assert specifier.operator == "==", line
            pins[requirement.name] = specifier.version
    return pins


def test_every_lower_bound_is_the_version_the_oldest_job_pins():
    pins = pinned_versions()
    bounds = {}
    for requirement in declared_requirements():
        if requirement.name in OUTSIDE_THE_SUITE:
            continue
        lower = [spec.version for spec in requirement.specifier if spec.operator == ">="]
        assert len(lower) == 1, f"{requirement}: one lower bound (>=), the version .ci/oldest tests"
        assert bounds.setdefault(requirement.name, lower[0]) == lower[0], f"{requirement.name}: two lower bounds"
        assert requirement.name in pins, f"{requirement.name} is not pinned in .ci/oldest-constraints.txt"
        # ">=2.2" is tested as 2.2.0: compared as versions, not strings
        assert Requirement(f"x=={lower[0]}").specifier.contains(pins[requirement.name]), (requirement, pins)
    assert set(pins) == set(bounds), "a pin for a package wbc does not require"


def test_pinocchio_3_is_supported():
    """The issue this job exists for: pin 3.x (no kinematic-Hessian binding) must stay in range."""
    assert pinned_versions()["pin"].startswith("3.")
