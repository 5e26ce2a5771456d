"""The structures a case can build, one module each: its section, and what else it owns.

A case builds one structure: the wall, unless it gives the section of another (``arch``,
``vault``, ``assembly``). Each structure module defines ``STRUCTURE``, a :class:`Structure`:
the section's name and model, the other parts of the case that only such a structure reads
(``owns``: the wall's ``supports`` and push, a limit state's ``collapse`` and growing loads),
and the checks of the whole case that concern it and need nothing but the case. The case
model (``case/model.py``) takes its structure sections from :func:`structures`, so a new
structure is a new module here (and its builder in ``scenes/``).

A part owned by other structures and not by the case's own is refused when given, and left out
of the case written back.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from typing import Any


@dataclass(frozen=True)
class Structure:
    """A kind of structure a case builds (module docstring).

    ``name``: its section in the case (and the builder's name); ``model``: the section's model;
    ``description``: the section's description in the case; ``article``: how messages name a
    case of it (``a wall``, ``an arch``); ``owns``: the dotted paths of the case, its section
    included, that only this kind of structure reads; ``limit_state``: its runs end in collapse
    or standing (a ``collapse`` rule, growing loads); ``order``: its place among the sections
    of the case (the default structure, 0, first); ``checks(case)``: the problems of the case
    as ``(dotted path, text)`` that concern this structure (none by default)."""

    name: str
    model: type
    description: str
    article: str
    owns: tuple[str, ...]
    limit_state: bool
    order: int
    checks: Callable[[Any], list[tuple[str, str]]] = field(default=lambda case: [])

    @property
    def default(self) -> bool:
        """Whether this is the structure of a case that names none (the wall)."""
        return self.order == 0


@cache
def structures() -> tuple[Structure, ...]:
    """Every structure of this package, by ``order``: the ``STRUCTURE`` of each module."""
    found = []
    for info in pkgutil.iter_modules(__path__):
        module = importlib.import_module(f"{__name__}.{info.name}")
        if hasattr(module, "STRUCTURE"):
            found.append(module.STRUCTURE)
    found.sort(key=lambda s: s.order)
    if not found or not found[0].default or sum(s.default for s in found) != 1:
        raise RuntimeError("the structures need exactly one default (order 0)")
    return tuple(found)


def named(name: str) -> Structure:
    """The structure whose section is ``name`` (KeyError if none)."""
    for s in structures():
        if s.name == name:
            return s
    raise KeyError(name)
