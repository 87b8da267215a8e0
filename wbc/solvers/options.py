"""Validation of ``solver_options``: known keys, sane values, one way to give a budget.

Each backend's valid keys are read from the backend itself (its settings object or
option list), plus the qpsolvers-level ``verbose``, wbc's ``warm_start`` and the generic
budget keys of :data:`BUDGET_KEYS`, which are translated to the backend's own names.
"""

from __future__ import annotations

import difflib
import math
import numbers
import re
from functools import cache
from typing import Any

from ..core.errors import InvalidInputError
from ..core.quiet import silenced

#: generic budget key -> the backend's own setting; a backend without an entry cannot
#: honour that budget (quadprog runs to completion, ProxQP and PIQP have no clock)
BUDGET_KEYS: dict[str, dict[str, str]] = {
    "daqp": {"time_limit": "time_limit", "max_iter": "iter_limit"},
    "osqp": {"time_limit": "time_limit", "max_iter": "max_iter"},
    "proxqp": {"max_iter": "max_iter"},
    "clarabel": {"time_limit": "time_limit", "max_iter": "max_iter"},
    "piqp": {"max_iter": "max_iter"},
    "highs": {"time_limit": "time_limit", "max_iter": "qp_iteration_limit"},
    "quadprog": {},
}
GENERIC_BUDGETS = ("time_limit", "max_iter")

_BUDGET = re.compile(r"(time_limit|iter_limit|iteration_limit|max_iter)$")
_TOLERANCE = re.compile(r"(^eps_|tol)")
#: OSQP keeps its flags as C ints; these are booleans
_OSQP_FLAGS = ("adaptive_rho", "check_dualgap", "polishing", "polish", "rho_is_vec", "scaled_termination",
               "verbose", "warm_starting", "raise_error")


class InvalidSolverOptionError(InvalidInputError):
    """A ``solver_options`` key is unknown to the backend, or its value is out of range."""


def _attributes(settings: object) -> dict[str, object]:
    """Public data attributes of a settings object, with their defaults."""
    names = (name for name in dir(settings) if not name.startswith("_"))
    return {name: value for name in names if not callable(value := getattr(settings, name))}


def _signature_defaults(function: object, data: tuple[str, ...]) -> dict[str, object]:
    """Keyword names of a compiled function (from its docstring signature), typed defaults."""
    signature = (function.__doc__ or "").split("\n", 1)[0]
    kinds = {"bool": False, "int": 0, "float": 0.0}
    names = re.findall(r"(\w+): ([\w.]+)", signature)
    return {name: kinds.get(kind) for name, kind in names if name not in data}


def _daqp() -> dict[str, object]:
    import daqp

    return dict(daqp.Model().settings)


def _osqp() -> dict[str, object]:
    from osqp import ext_builtin

    settings = ext_builtin.OSQPSettings()
    ext_builtin.osqp_set_default_settings(settings)
    keys = {**_attributes(settings), "polish": 1, "solver_type": "direct", "cg_preconditioner": "diagonal",
            "raise_error": False}
    return {key: bool(value) if key in _OSQP_FLAGS else value for key, value in keys.items()}


def _proxqp() -> dict[str, object]:
    from proxsuite import proxqp

    data = ("H", "g", "A", "b", "C", "l", "u", "l_box", "u_box", "x", "y", "z")
    return {**_signature_defaults(proxqp.sparse.solve, data), "backend": None}


def _clarabel() -> dict[str, object]:
    import clarabel

    return _attributes(clarabel.DefaultSettings())


def _piqp() -> dict[str, object]:
    import piqp

    return {**_attributes(piqp.SparseSolver().settings), "backend": None}


def _highs() -> dict[str, object]:
    import highspy

    with silenced():  # highspy >= 1.16 prints a banner on stdout when its first Highs() is made
        solver = highspy.Highs()
    return _attributes(solver.getOptions())


_SETTINGS = {"daqp": _daqp, "osqp": _osqp, "proxqp": _proxqp, "clarabel": _clarabel, "piqp": _piqp,
             "highs": _highs, "quadprog": dict}


@cache
def valid_options(name: str) -> dict[str, object] | None:
    """Every key ``solver_options`` may hold for backend ``name``, with its default
    (None: unknown type); None for a backend whose settings wbc cannot list."""
    if name not in _SETTINGS:
        return None
    keys = {"warm_start": True, **_SETTINGS[name]()}
    if name != "daqp":
        keys.setdefault("verbose", False)  # qpsolvers' own argument
    for generic in BUDGET_KEYS.get(name, {}):
        keys.setdefault(generic, 0.0)
    return keys


def _check_key(name: str, key: object, valid: dict[str, object] | None) -> None:
    if not isinstance(key, str):
        raise InvalidSolverOptionError(f"solver option names are strings, got {key!r}")
    if key in GENERIC_BUDGETS and name in BUDGET_KEYS and key not in BUDGET_KEYS[name]:
        able = ", ".join(solver for solver, keys in BUDGET_KEYS.items() if key in keys)
        raise InvalidSolverOptionError(f"{name} cannot honour a {key} budget; backends that can: {able}")
    if valid is None or key in valid:
        return
    close = difflib.get_close_matches(key, valid, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    raise InvalidSolverOptionError(f"unknown option {key!r} for solver {name}{hint}; "
                                   f"valid keys: {', '.join(sorted(valid))}")


def _check_value(name: str, key: str, value: object, default: object) -> object:
    """``value``, checked for ``key`` (an iteration budget given as a whole float: that int)."""
    where = f"solver option {key!r} of {name}"
    if isinstance(default, bool) or key == "warm_start":
        if not isinstance(value, bool):
            raise InvalidSolverOptionError(f"{where} must be a bool, got {value!r}")
        return value
    budget, tolerance = _BUDGET.search(key), _TOLERANCE.search(key) and not (
        isinstance(default, numbers.Real) and default < 0)
    if not (isinstance(default, numbers.Real) or budget or tolerance):
        return value  # not a number: the backend checks it
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InvalidSolverOptionError(f"{where} must be a number, got {value!r}")
    number = float(value)
    if budget and not (math.isfinite(number) and number > 0):
        raise InvalidSolverOptionError(f"{where} is a budget: it must be finite and > 0, got {value!r}")
    if tolerance and not (math.isfinite(number) and number >= 0):
        raise InvalidSolverOptionError(f"{where} is a tolerance: it must be finite and >= 0, got {value!r}")
    if budget and budget.group(1) != "time_limit" and not isinstance(value, numbers.Integral):
        if not number.is_integer():
            raise InvalidSolverOptionError(f"{where} counts iterations: it must be a whole number, got {value!r}")
        return int(number)
    return value


def validate_options(name: str, options: dict[str, Any] | None) -> dict[str, Any]:
    """Checked copy of ``options`` for backend ``name``, generic budgets translated to its
    own keys; raises :class:`InvalidSolverOptionError` naming the key, solver and valid keys."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise InvalidSolverOptionError(f"solver_options must be a dict, got {type(options).__name__}")
    valid = valid_options(name)
    checked: dict[str, Any] = {}
    for key, value in options.items():
        _check_key(name, key, valid)
        value = _check_value(name, key, value, None if valid is None else valid.get(key))
        own = BUDGET_KEYS.get(name, {}).get(key, key)
        if own in checked and checked[own] != value:
            raise InvalidSolverOptionError(f"{name}: {key!r} and {own!r} give two different budgets")
        checked[own] = value
    return checked
