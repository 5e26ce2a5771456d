"""The ``--set PATH=VALUE`` overrides of a case file's data."""

from __future__ import annotations

import re
from types import UnionType
from typing import Any, Union, get_args, get_origin

from pydantic import BaseModel

from masonry_nscd.case.errors import CaseError
from masonry_nscd.case.messages import is_model, show, split_annotated, suggest
from masonry_nscd.case.yaml12 import read_yaml

_PART = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


def _list_item(annotation: Any) -> Any | None:
    """The item type of a list field (``list[T]``, ``list[T] | None``), or None."""
    annotation, _ = split_annotated(annotation)
    options = get_args(annotation) if get_origin(annotation) in (Union, UnionType) \
        else (annotation,)
    for option in options:
        option, _ = split_annotated(option)
        if get_origin(option) is list:
            return get_args(option)[0]
    return None


def _as_model(annotation: Any) -> Any:
    """A section type, or the section among the options of a union (``list[float] | Course``)."""
    annotation, _ = split_annotated(annotation)
    if get_origin(annotation) in (Union, UnionType):
        models = [a for a in get_args(annotation) if is_model(split_annotated(a)[0])]
        if models:
            return split_annotated(models[0])[0]
    return annotation


def apply_override(data: dict, override: str, root: type[BaseModel]) -> None:
    """Apply one ``dotted.path=value`` override to raw data of the schema ``root`` (in place);
    a part may index a list (``wall.openings[0].x_m``)."""
    if not isinstance(override, str) or "=" not in override:
        raise CaseError(
            f"--set {override}: an override must be PATH=VALUE, e.g. joint.mu=0.5 or "
            "wall.elements_per_unit=[1,1,1]"
        )
    path_text, value_text = override.split("=", 1)
    parts = [p.strip() for p in path_text.strip().split(".")]
    if not path_text.strip() or any(not p for p in parts):
        raise CaseError(f"--set {override}: the path before '=' is empty or has an empty part")
    steps: list[tuple[str, int | None]] = []
    annotation: Any = root
    for i, part in enumerate(parts):
        annotation = _as_model(annotation)
        here = ".".join(parts[:i]) or "the top level"
        if not is_model(annotation):
            raise CaseError(
                f"--set {override}: {'.'.join(parts[:i])} is a value, not a section; it has "
                f"no key '{part}'"
            )
        m = _PART.match(part)
        key, index = (m.group(1), m.group(2)) if m else (part, None)
        fields = annotation.model_fields
        if key not in fields:
            raise CaseError(
                f"--set {override}: unknown path {'.'.join(parts[: i + 1])}"
                f"{suggest(key, list(fields))}; the keys allowed in {here} are: "
                + ", ".join(fields)
            )
        annotation = fields[key].annotation
        if index is not None:
            item = _list_item(annotation)
            if item is None:
                raise CaseError(f"--set {override}: {'.'.join(parts[:i] + [key])} is not a "
                                "list: it takes no [index]")
            annotation = item
        steps.append((key, None if index is None else int(index)))
    if annotation is str:
        value: Any = value_text  # text fields take the text as given
    else:
        value = read_yaml(value_text, f"--set {override}")
    target: Any = data
    for i, (key, index) in enumerate(steps):
        last = i == len(steps) - 1
        where = ".".join(parts[: i + 1])
        if index is None:
            if last:
                target[key] = value
                return
            child = target.get(key)
            if child is None:
                child = target[key] = {}
        else:
            items = target.get(key)
            if not isinstance(items, list) or not index < len(items):
                count = len(items) if isinstance(items, list) else 0
                raise CaseError(f"--set {override}: {'.'.join(parts[:i] + [key])} has {count} "
                                f"item{'s' if count != 1 else ''} in the case file: no [{index}]")
            if last:
                items[index] = value
                return
            child = items[index]
        if not isinstance(child, dict):
            raise CaseError(
                f"--set {override}: {where} in the case file is {show(child)}, not a mapping"
            )
        target = child
