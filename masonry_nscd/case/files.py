"""Reading, validating and writing case files."""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from masonry_nscd.case.errors import CaseError
from masonry_nscd.case.messages import messages, show
from masonry_nscd.case.model import Case
from masonry_nscd.case.overrides import apply_override
from masonry_nscd.case.yaml12 import format_scalar, read_yaml


def case_from_dict(data: Any, *, case_dir: str | Path | None = None,
                   check_files: bool = False) -> Case:
    """Validate a mapping (as read from a case file) into a :class:`Case`.

    ``case_dir``: the folder relative paths of the case (``loading.horizontal.file``) are
    read from, and made absolute with (None: left as they are, i.e. relative to the working
    folder). ``check_files``: read the files the case names and refuse one that cannot be
    used. Raises :class:`CaseError` with one message per problem.
    """
    if not isinstance(data, Mapping):
        raise CaseError(
            f"the case: got {show(data)}; a case must be a mapping with the keys "
            + ", ".join(Case.model_fields)
        )
    try:
        return Case.model_validate(dict(data), context={"case_dir": case_dir,
                                                        "check_files": check_files})
    except ValidationError as exc:
        raise CaseError(messages(exc, Case)) from None
    except RecursionError:
        raise CaseError(
            "the case: the data is nested too deeply (a recursive YAML alias?)"
        ) from None


def load_case(path: str | Path, overrides: Sequence[str] = (), *,
              check_files: bool = True) -> Case:
    """Read, override and validate a case file.

    A relative path in the case (``loading.horizontal.file``) is relative to the case file's
    folder and made absolute; with ``check_files`` (the default) the file is read and checked
    (the summary and the plots of a run folder pass False: they do not need it).

    ``overrides`` are ``dotted.path=value`` strings (the CLI's ``--set``), applied in order; the
    value is parsed as YAML (``0.3e6`` is a float, ``[2,2,1]`` a list, ``true`` a boolean; a
    text field such as ``name`` takes the text as given) and the path must exist in the schema.
    ``name`` defaults to the file's stem. Raises :class:`CaseError` for every problem.
    """
    path = Path(path)
    source = str(path)
    if not path.exists():
        raise CaseError(f"{source}: case file not found")
    if path.is_dir():
        raise CaseError(f"{source}: is a directory, not a case file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise CaseError(
            f"{source}: not a UTF-8 text file ({exc.reason} at byte {exc.start})"
        ) from None
    except OSError as exc:
        raise CaseError(f"{source}: cannot read the file: {exc.strerror or exc}") from None
    data = read_yaml(text, source)
    if data is None:
        raise CaseError(
            f"{source}: the file is empty; a case file is a mapping (use '{{}}' for all defaults)"
        )
    if not isinstance(data, dict):
        raise CaseError(
            f"{source}: the top level must be a mapping with the keys "
            f"{', '.join(Case.model_fields)}; got {show(data)}"
        )
    data = copy.deepcopy(data) if overrides else data
    for override in overrides:
        apply_override(data, override, Case)
    data.setdefault("name", path.stem)
    return case_from_dict(data, case_dir=path.parent, check_files=check_files)


def _emit(model: BaseModel, indent: int, lines: list[str], comments: bool,
          skip: Sequence[str] = (), prefix: str = "") -> None:
    pad = "  " * indent
    for name, info in type(model).model_fields.items():
        if f"{prefix}{name}" in skip:
            continue
        value = getattr(model, name)
        comment = f"  # {info.description}" if comments and info.description else ""
        if isinstance(value, BaseModel):
            lines.append(f"{pad}{name}:{comment}")
            _emit(value, indent + 1, lines, comments, skip, f"{prefix}{name}.")
        else:
            lines.append(f"{pad}{name}: {format_scalar(value)}{comment}")


def case_to_yaml(case: Case, *, comments: bool = True) -> str:
    """The full case as YAML, every default filled in, in schema order.

    Floats are written so that they read back as floats with any YAML reader (``1.1e+10``,
    ``0.3``); with ``comments`` each line carries the field's description and unit.
    ``load_case`` of the text gives back an equal :class:`Case`.
    """
    lines = ["# masonry_nscd case file; SI units (m, Pa, N, J, s, kg)"] if comments else []
    _emit(case, 0, lines, comments, case.unused_sections())
    return "\n".join(lines) + "\n"
