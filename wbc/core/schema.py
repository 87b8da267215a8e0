"""Strict schemas for wbc's TOML files (scenarios, model sidecars), built on pydantic v2.

wbc uses pydantic rather than hand-written checks because its strict mode refuses
``"0.01"`` or ``true`` for a number and ``"false"`` for a boolean, ``extra="forbid"``
catches every misspelt key, and each error carries its location in the file, which
:func:`explain` turns into one line naming the table, the key and the fix.
"""

from __future__ import annotations

import difflib
import sys
import types
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from .errors import WbcError

if TYPE_CHECKING:  # pragma: no cover
    from pydantic_core import ErrorDetails

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

Positive = Annotated[float, Field(gt=0.0)]
NonNegative = Annotated[float, Field(ge=0.0)]
Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]


def read_toml(path: Path, error: type[WbcError], what: str = "") -> dict[str, Any]:
    """The tables of the TOML file ``path``; an unreadable file, a syntax error or bytes that are
    not UTF-8 raise ``error`` saying ``cannot read {what} {path}: ...`` and the fix."""
    where = f"{what} {path}" if what else str(path)
    try:
        with open(path, "rb") as stream:
            return tomllib.load(stream)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise error(f"cannot read {where}: {exc}") from exc
    except UnicodeDecodeError as exc:
        raise error(f"cannot read {where}: not UTF-8 text (byte {exc.object[exc.start]:#04x} at offset "
                    f"{exc.start}); TOML files are UTF-8: save it as UTF-8") from None


class Table(BaseModel):
    """A TOML table: strict types, no unknown keys, no inf/nan."""

    model_config = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False, frozen=True)


def suggest(word: object, valid: Iterable[object]) -> str:
    """``"; did you mean 'x'?"`` for the closest valid name, or ``""``."""
    close = difflib.get_close_matches(str(word), [str(v) for v in valid], n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def explain(error: ValidationError, schema: type[BaseModel]) -> str:
    """One line per problem, ``[table] key: what is wrong; the fix`` (several are indented lines)."""
    lines = [_explain_one(item, schema) for item in error.errors(include_url=False)]
    return lines[0] if len(lines) == 1 else "\n  " + "\n  ".join(lines)


def _is_model(annotation: Any) -> bool:
    return isinstance(annotation, type) and issubclass(annotation, BaseModel)


def _nested(annotation: Any) -> tuple[str, Any] | None:
    """How a field's value continues the path: ("table", model), ("array", model),
    ("union", {tag: model}) or None for a plain value."""
    origin, args = get_origin(annotation), [a for a in get_args(annotation) if a is not type(None)]
    if origin is Annotated or (origin in (Union, types.UnionType) and len(args) == 1):
        return _nested(args[0])
    if _is_model(annotation):
        return "table", annotation
    if origin is list and args and _is_model(args[0]):
        return "array", args[0]
    if origin in (Union, types.UnionType):
        models = [a for a in args if _is_model(a)]
        if len(models) == 1:
            return "table", models[0]
        if models:
            return "union", {tag: m for m in models for tag in _tags(m)}
    return None


def _tags(model: type[BaseModel]) -> tuple[Any, ...]:
    """The literal values of a union member's discriminator (its first Literal field)."""
    for field in model.model_fields.values():
        if get_origin(field.annotation) is Literal:
            return get_args(field.annotation)
    raise TypeError(f"{model.__name__} has no Literal discriminator")


def _locate(schema: type[BaseModel], loc: tuple[int | str, ...]) -> tuple[str, str, type[BaseModel] | None]:
    """(table header, key, model holding the key) of an error location."""
    model: type[BaseModel] | None = schema
    names: list[str] = []
    header, key = "top level", ""
    pending: tuple[str, Any] | None = None
    for part in loc:
        if key:
            key += f"[{part}]"
        elif pending and pending[0] == "array":
            header, pending = f"[[{'.'.join(names)}]] #{int(part) + 1}", None
        elif pending and pending[0] == "union":
            model, pending = pending[1].get(part, model), None
        elif model is not None and isinstance(part, str) and part in model.model_fields:
            nested = _nested(model.model_fields[part].annotation)
            if nested is None:
                key = part
                continue
            names.append(part)
            header = f"[{'.'.join(names)}]"
            pending = nested if nested[0] != "table" else None
            model = nested[1] if nested[0] != "union" else model
        else:
            key = str(part)
    return header, key, model


def _explain_one(item: ErrorDetails, schema: type[BaseModel]) -> str:
    header, key, model = _locate(schema, item["loc"])
    kind, value = item["type"], item.get("input")
    where = f"{header} {key}".strip() if key else header
    fields = list(model.model_fields) if model is not None else []
    if kind == "extra_forbidden":
        place = "section or key" if header == "top level" else "key"
        return (f"unknown {place} {key!r} in {header}{suggest(key, fields)} "
                f"(valid: {', '.join(fields)})")
    if kind == "missing":
        return f"{where}: required key missing; add `{key} = ...` to {header}" if key else f"{where} is missing; add it"
    if kind in ("union_tag_invalid", "union_tag_not_found", "literal_error"):
        return _explain_choice(item, where, model, key)
    if kind in ("float_type", "int_type", "bool_type", "string_type", "list_type", "dict_type", "model_type"):
        return f"{where} = {value!r}: {item['msg'].replace('Input', 'value')}; {_type_fix(kind, value)}"
    if kind == "finite_number":
        return f"{where} = {value!r}: must be a finite number (no inf or nan)"
    message = item["msg"].removeprefix("Value error, ")
    return f"{where} = {value!r}: {message[0].lower()}{message[1:]}" if key else f"{where}: {message}"


def _explain_choice(item: ErrorDetails, where: str, model: type[BaseModel] | None, key: str) -> str:
    """Unknown or missing ``type`` / ``kind`` tags and literal values, with suggestions."""
    context = item.get("ctx", {})
    if item["type"] == "literal_error" and model is not None and key in model.model_fields:
        choices = [str(c) for c in get_args(model.model_fields[key].annotation)]
    else:
        choices = [c.strip(" '") for c in str(context.get("expected_tags", "")).split(",") if c.strip()]
    name = context.get("discriminator", "").strip("'") or key
    if item["type"] == "union_tag_not_found":
        return f"{where}: needs {name} = one of {', '.join(choices)}"
    given = context.get("tag", item.get("input"))
    return f"{where} {name} = {given!r} unknown{suggest(given, choices)} (known: {', '.join(choices)})"


def _type_fix(kind: str, value: Any) -> str:
    expected = {"float_type": "a number", "int_type": "an integer", "bool_type": "true or false",
                "string_type": "a quoted string", "list_type": "an array [...]",
                "dict_type": "a table", "model_type": "a table"}[kind]
    if isinstance(value, str) and kind in ("float_type", "int_type", "bool_type"):
        return f"write {expected} without quotes"
    return f"write {expected}"


__all__ = ["Table", "Positive", "NonNegative", "Vector3", "explain", "suggest"]
