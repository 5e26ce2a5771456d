"""Readable messages from the schema: a field's path, the value given and what is allowed."""

from __future__ import annotations

import difflib
from collections.abc import Mapping, Sequence
from typing import Annotated, Any, Literal, get_args, get_origin

from pydantic import BaseModel, ValidationError

from masonry_nscd.case.fields import SQRT3

#: The units a field's name ends with, the longer suffixes first (``rate_per_s`` is 1/s, not s)
UNIT_SUFFIXES = (
    ("_kg_m3", "kg/m^3"),
    ("_J_m2", "J/m^2"),
    ("_m_s2", "m/s^2"),
    ("_Pa_m", "Pa/m"),
    ("_per_s", "1/s"),
    ("_m_s", "m/s"),
    ("_N_m", "N/m"),
    ("_N_s", "N/s"),
    ("_deg", "degrees"),
    ("_Pa", "Pa"),
    ("_kg", "kg"),
    ("_N", "N"),
    ("_J", "J"),
    ("_s", "s"),
    ("_m", "m"),
)


def unit_of(name: str) -> str | None:
    """The unit a field's name ends with (``E_Pa``: Pa), or None."""
    for suffix, unit in UNIT_SUFFIXES:
        if name.endswith(suffix):
            return unit
    return None


def is_model(annotation: Any) -> bool:
    return isinstance(annotation, type) and issubclass(annotation, BaseModel)


def split_annotated(annotation: Any) -> tuple[Any, list[Any]]:
    """``Annotated[T, FieldInfo(...), ...]`` -> ``(T, metadata of the FieldInfo parts)``."""
    metadata: list[Any] = []
    if get_origin(annotation) is Annotated:
        base, *extras = get_args(annotation)
        for extra in extras:
            metadata.extend(getattr(extra, "metadata", [extra]))
        return base, metadata
    return annotation, metadata


def _fmt_bound(value: Any) -> str:
    if isinstance(value, float) and value == SQRT3:
        return "sqrt(3)"
    return f"{value:g}" if isinstance(value, (int, float)) else str(value)


def describe(annotation: Any, metadata: Sequence[Any], name: str = "") -> str:
    """What a field accepts, in words: 'a number, 0 <= value < 1', "one of 'a', 'b'", ..."""
    annotation, extra = split_annotated(annotation)
    metadata = list(metadata) + extra
    if get_origin(annotation) is Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(annotation))
    if annotation is bool:
        return "true or false"
    if annotation is str:
        return "text"
    if is_model(annotation):
        return "a mapping with the keys " + ", ".join(annotation.model_fields)
    if get_origin(annotation) is tuple:
        args = get_args(annotation)
        return f"a list of {len(args)} items, each " + describe(args[0], [])
    if annotation in (int, float):
        low = high = ""
        for m in metadata:
            if getattr(m, "gt", None) is not None:
                low = f"{_fmt_bound(m.gt)} < "
            if getattr(m, "ge", None) is not None:
                low = f"{_fmt_bound(m.ge)} <= "
            if getattr(m, "lt", None) is not None:
                high = f" < {_fmt_bound(m.lt)}"
            if getattr(m, "le", None) is not None:
                high = f" <= {_fmt_bound(m.le)}"
        text = "a whole number" if annotation is int else "a number"
        if low or high:
            text += f", {low}value{high}"
        unit = unit_of(name)
        if unit:
            text += f" (in {unit})"
        return text
    return str(annotation)


def lookup(root: type[BaseModel], loc: Sequence[Any]) -> tuple[Any, list[Any], str] | None:
    """The annotation, constraints and name of the node at ``loc`` of the schema ``root``
    (None if unknown)."""
    annotation: Any = root
    metadata: list[Any] = []
    name = ""
    for part in loc:
        annotation, _ = split_annotated(annotation)
        if is_model(annotation):
            if not isinstance(part, str) or part not in annotation.model_fields:
                return None
            info = annotation.model_fields[part]
            annotation, metadata, name = info.annotation, list(info.metadata), part
        elif get_origin(annotation) is tuple and isinstance(part, int):
            args = get_args(annotation)
            if not 0 <= part < len(args):
                return None
            annotation, metadata = args[part], []
        else:
            return None
    return annotation, metadata, name


def path_text(loc: Sequence[Any]) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int) and not isinstance(part, bool):
            text += f"[{part}]"
        else:
            text += ("." if text else "") + str(part)
    return text


def show(value: Any) -> str:
    """A short rendering of a value given by the user."""
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    if value is None:
        return "null (no value)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, Mapping):
        return "a mapping " + text
    if isinstance(value, (list, tuple)):
        return "a list " + text
    return text


def _allowed_keys(root: type[BaseModel], loc: Sequence[Any]) -> list[str]:
    node = lookup(root, loc)
    if node is None:
        return []
    annotation, _ = split_annotated(node[0])
    return list(annotation.model_fields) if is_model(annotation) else []


def suggest(key: Any, allowed: Sequence[str]) -> str:
    close = difflib.get_close_matches(str(key), allowed, n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


_RANGE_ERRORS = frozenset(
    {"greater_than", "greater_than_equal", "less_than", "less_than_equal", "finite_number"}
)


def messages(error: ValidationError, root: type[BaseModel],
             prefix: Sequence[Any] = ()) -> list[str]:
    """Readable messages from a pydantic error of the schema ``root``: field path (after
    ``prefix``, the path of ``root`` in the case), value given, what is allowed."""
    messages: list[str] = []
    prefix = tuple(prefix)
    for err in error.errors():
        rel = tuple(err.get("loc", ()))
        loc = prefix + rel
        kind = err.get("type", "")
        value = err.get("input")
        ctx = err.get("ctx") or {}
        if kind == "case_consistency":
            for field, text in ctx.get("problems", []):
                messages.append(f"{path_text(loc + (field,))}: {text}")
            continue
        if kind in ("extra_forbidden", "invalid_key"):
            parent, key = loc[:-1], (loc[-1] if loc else "?")
            allowed = _allowed_keys(root, rel[:-1])
            where = path_text(parent) or "the top level"
            if kind == "extra_forbidden":
                what, shown = "unknown field", path_text(loc)
            else:
                what, shown = (
                    "a key must be text",
                    ".".join(filter(None, [path_text(parent), repr(value)])),
                )
            messages.append(
                f"{shown}: {what}{suggest(key, allowed)}; the keys allowed in {where} "
                f"are: {', '.join(allowed)}"
            )
            continue
        node = lookup(root, rel)
        allowed = describe(*node) if node is not None else ""
        if kind in _RANGE_ERRORS and allowed:
            reason = "out of range"
        elif kind == "literal_error" and allowed:
            reason = "not a valid choice"
        else:
            reason = str(err.get("msg", "invalid value"))
            reason = reason[:1].lower() + reason[1:]
        text = f"{path_text(loc) or 'the case'}: got {show(value)}; {reason}"
        if allowed:
            text += f"; allowed: {allowed}"
        messages.append(text)
    return messages or [str(error)]
