"""Scene builders: a case's structure turned into a block assembly ready to step.

Every structure of the case schema (``case/structures/``) has a builder here, the module of
its name (``scenes/wall.py`` for ``wall``), which defines ``BUILDER``, a :class:`Builder`: the structure it builds, ``build(case) -> Scene``,
``describe(case)`` (the one line of ``masonry validate``) and ``check(case)``, the problems of
a case that need the builder's own geometry (a wall's layout, an assembly's mesh file) and so
are not the schema's. ``build_scene(case)`` and ``check_case(case)`` find the builder of the
case's structure here; nothing else asks which structure a case has. A new structure is its
section module in ``case/structures/`` and its builder module here.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from typing import Any

from masonry_nscd.case import CaseError
from masonry_nscd.case.structures import structures
from masonry_nscd.nscd import linear
from masonry_nscd.scenes.removal import removal_of


@dataclass(frozen=True)
class Builder:
    """The builder of one structure (module docstring): ``structure`` is the name of its
    section; ``check(case)`` gives ``(dotted path, text)`` problems."""

    structure: str
    build: Callable[[Any], Any]
    describe: Callable[[Any], str]
    check: Callable[[Any], list[tuple[str, str]]] = field(default=lambda case: [])


def builders() -> dict[str, Builder]:
    """The builder of every structure of the schema, by the structure's name."""
    return {s.name: _builder(s.name) for s in structures()}


def builder_of(case) -> Builder:
    """The builder of the case's structure."""
    return _builder(case.structure.name)


@cache
def _builder(name: str) -> Builder:
    """The ``BUILDER`` of module ``scenes/<name>.py``, imported only when asked for."""
    builder = importlib.import_module(f"{__name__}.{name}").BUILDER
    if builder.structure != name:
        raise RuntimeError(f"scenes/{name}.py builds {builder.structure!r}, not {name!r}")
    return builder


def describe_case(case) -> str:
    """The one line of ``masonry validate``: the builder's, and the loads on named blocks and
    the removal that every limit-state structure takes."""
    line = builder_of(case).describe(case)
    ld = case.loading
    extra = [f"a line load of {load.length_m:.4g} m on {', '.join(load.blocks)}"
             for load in ld.line_loads]
    extra += [f"a force on each of {', '.join(load.blocks)}" for load in ld.block_loads]
    extra += [f"{', '.join(group.blocks)} removed at {group.time_s:g} s"
              for _, group in sorted(ld.removal_groups(), key=lambda g: g[1].time_s)]
    return line + "".join(f"; {e}" for e in extra)


def problems(case) -> list[str]:
    """What the schema does not see wrong with a valid case: its builder's checks, and a
    linear solver this machine does not have. One message per problem, naming the field."""
    found = builder_of(case).check(case)
    if case.solver.linear == "pardiso":
        try:
            linear.choose("pardiso", 1)
        except ValueError as exc:
            found.append(("solver.linear", f"got pardiso; {exc}"))
    return [f"{path}: {text}" for path, text in found]


def check_case(case):
    """``case``, if its builder finds no problem (:func:`problems`); CaseError otherwise."""
    found = problems(case)
    if found:
        raise CaseError(found)
    return case


def build_scene(case):
    """The scene of a validated case (CaseError when its builder refuses it), with the removal
    of blocks the case asks for (``loading.removal``, :mod:`masonry_nscd.scenes.removal`)."""
    scene = builder_of(check_case(case)).build(case)
    scene.removal = removal_of(case, scene.bodies)
    return scene
