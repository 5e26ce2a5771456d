"""The case file's reference, made from the case model: a JSON Schema of the YAML input (for
editors: completion, hover text, misspelt keys and values out of range flagged as one types)
and a Markdown page of every section and field (``masonry schema``; committed as
``docs/reference/case.schema.json`` and ``docs/reference/case.md``).

The JSON Schema is pydantic's (draft 2020-12), made to describe the file as users write it:

- bounds are JSON Schema keywords everywhere (pydantic writes the bounds of a list's items,
  ``list[Annotated[Real, Field(ge=...)]]``, as ``ge``/``le``, which no validator reads);
- a default made by a factory is given when it is a value (``joint.scatter.fields``), not when
  it is a whole section (each field of the section has its own);
- ``name`` has no default there: it is the case file's stem;
- a joint region's numbers, which replace the joint's, take the joint's bounds;
- the rule of the structures (``structures/``): a case builds one structure, and the parts of
  the case that only other structures read are refused (``supports`` with an arch,
  ``collapse`` with a wall), as ``if``/``then`` rules made from each structure's ``owns``;
- sections forbid unknown keys (``additionalProperties: false``, from ``extra="forbid"``).

It is stricter than ``masonry validate`` in one place: numbers must be written as numbers
(the validation also converts numeric text, ``"0.3e6"``). It checks each field on its own and
the structure rule; the checks across fields (the running bond's half unit, a pointed arch's
radius, the joint's fracture energies, the blocks named by loads, the files) are
``masonry validate``'s.

The Markdown page is made from the JSON Schema (the same types, bounds, defaults and
descriptions) and the structures' ``owns`` (which structure reads a section).
"""

from __future__ import annotations

import copy
import json
import re
import types
from typing import Any, Union, get_args, get_origin

from pydantic import BaseModel
from pydantic.json_schema import GenerateJsonSchema, NoDefault

from masonry_nscd.case.fields import SQRT3
from masonry_nscd.case.joint import REGION_FIELDS
from masonry_nscd.case.messages import UNIT_SUFFIXES, split_annotated, unit_of
from masonry_nscd.case.model import Case
from masonry_nscd.case.structures import structures

DRAFT = "https://json-schema.org/draft/2020-12/schema"
#: Where the reference is committed, relative to the repository
MARKDOWN_FILE = "docs/reference/case.md"
JSON_FILE = "docs/reference/case.schema.json"
#: The commands that write them (``make reference`` runs both)
REGENERATE = (f"masonry schema --markdown -o {MARKDOWN_FILE} && "
              f"masonry schema --json -o {JSON_FILE}")

_BOUNDS = {"ge": "minimum", "gt": "exclusiveMinimum", "le": "maximum", "lt": "exclusiveMaximum"}
_SUBSCHEMA_LISTS = ("anyOf", "oneOf", "allOf", "prefixItems")


class _Generator(GenerateJsonSchema):
    """Pydantic's generator, with the defaults made by a factory when they are values."""

    def get_default_value(self, schema: Any) -> Any:
        factory = schema.get("default_factory")
        if factory is None or schema.get("default_factory_takes_data"):
            return super().get_default_value(schema)
        value = factory()
        return NoDefault if isinstance(value, BaseModel) else value


def rst_to_markdown(text: str) -> str:
    """A docstring's reStructuredText made Markdown: ````x```` and roles (``:class:`X```) as
    code, a paragraph ending in ``::`` followed by a fenced block of its indented lines."""
    text = re.sub(r":(?:class|func|mod|attr|data|meth):`~?([^`]+)`", r"`\1`", text)
    text = text.replace("``", "`")
    lines, out, i = text.split("\n"), [], 0
    while i < len(lines):
        line = lines[i]
        i += 1
        if not line.rstrip().endswith("::"):
            out.append(line)
            continue
        out.append(line.rstrip()[:-1])
        base = len(line) - len(line.lstrip())
        block = []
        while i < len(lines) and (not lines[i].strip()
                                  or len(lines[i]) - len(lines[i].lstrip()) > base):
            block.append(lines[i])
            i += 1
        while block and not block[0].strip():
            block.pop(0)
        while block and not block[-1].strip():
            block.pop()
        indent = min((len(b) - len(b.lstrip()) for b in block if b.strip()), default=0)
        out += ["", "```", *(b[indent:] for b in block), "```", ""]
    return re.sub(r"\n{3,}", "\n\n", "\n".join(out)).strip()


def _fix(node: Any) -> Any:
    """A pydantic JSON Schema node made the file's: JSON Schema bound keywords, no titles,
    descriptions in Markdown."""
    if isinstance(node, list):
        return [_fix(n) for n in node]
    if not isinstance(node, dict):
        return node
    out: dict[str, Any] = {}
    for key, value in node.items():
        if key in ("properties", "$defs"):
            out[key] = {name: _fix(sub) for name, sub in value.items()}
        elif key == "title":
            continue
        elif key in _BOUNDS and node.get("type") in ("number", "integer"):
            out[_BOUNDS[key]] = value
        elif key == "description" and isinstance(value, str):
            out[key] = rst_to_markdown(value)
        elif isinstance(value, dict) or key in _SUBSCHEMA_LISTS or key == "items":
            out[key] = _fix(value)
        else:
            out[key] = value
    return out


def _nullable(model: type[BaseModel], name: str) -> bool:
    """Whether the field ``name`` of ``model`` takes null."""
    annotation, _ = split_annotated(model.model_fields[name].annotation)
    return get_origin(annotation) in (Union, types.UnionType) and \
        type(None) in get_args(annotation)


def _refused(paths: list[str]) -> dict[str, Any]:
    """A schema that refuses each dotted path of the case: absent, or null where the field takes
    null (a part owned by another structure, given, is an error; null is not given)."""
    schema: dict[str, Any] = {}
    for path in paths:
        model: type[BaseModel] = Case
        node = schema
        *parents, last = path.split(".")
        for part in parents:
            node = node.setdefault("properties", {}).setdefault(part, {})
            model = split_annotated(model.model_fields[part].annotation)[0]
        node.setdefault("properties", {})[last] = \
            {"type": "null"} if _nullable(model, last) else False
    return schema


def _structure_rules() -> list[dict[str, Any]]:
    """``if``/``then`` rules of the structures: for each, when the case builds it (its section is
    a mapping; the default structure: when no other's is), the parts of the case owned by the
    others and not by it are refused (the other structures' sections among them)."""
    every = structures()
    given = {s.name: {"required": [s.name], "properties": {s.name: {"type": "object"}}}
             for s in every}
    rules = []
    for own in every:
        others = [p for s in every if s is not own for p in s.owns if p not in own.owns]
        condition = {"not": {"anyOf": [given[s.name] for s in every if not s.default]}} \
            if own.default else given[own.name]
        rules.append({"if": condition, "then": _refused(list(dict.fromkeys(others)))})
    return rules


def _region_bounds(defs: dict[str, Any]) -> None:
    """A joint region's numbers take the bounds of the joint's (a region's values replace the
    joint's and are checked as the joint's: ``Joint._check_regions``)."""
    joint = defs["Joint"]["properties"]
    for name in REGION_FIELDS:
        node = defs["JointRegion"]["properties"][name]
        number = next(o for o in node["anyOf"] if o.get("type") == "number")
        number.update({k: v for k, v in joint[name].items() if k in _BOUNDS.values()})


def case_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a case file as users write it (module docstring)."""
    raw = _fix(Case.model_json_schema(mode="validation", schema_generator=_Generator))
    raw["properties"]["name"].pop("default", None)
    _region_bounds(raw["$defs"])
    schema: dict[str, Any] = {
        "$schema": DRAFT,
        "title": "masonry_nscd case file",
        "description": (
            "A simulation of masonry block by block (masonry_nscd): a YAML mapping of sections, "
            "SI units (m, Pa, N, J, s, kg). Reference: docs/reference/case.md; made by "
            "`masonry schema --json`."),
    }
    schema.update({k: v for k, v in raw.items() if k not in ("description",)})
    schema["allOf"] = _structure_rules()
    return schema


#: The order of the keywords in a node of the file written; the others after them, sorted
_KEYWORD_ORDER = ("$schema", "$ref", "title", "description", "type", "enum", "anyOf", "default",
                  "minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum", "minLength",
                  "maxLength", "minItems", "maxItems", "prefixItems", "items", "properties",
                  "required", "additionalProperties", "if", "then", "not", "allOf", "$defs")


def _canonical(node: Any) -> Any:
    """``node`` with its keywords in the order of :data:`_KEYWORD_ORDER` and the sections of
    ``$defs`` by name; the fields of ``properties`` stay in the model's order. The file so
    does not depend on the order in which pydantic writes a node's keywords."""
    if isinstance(node, list):
        return [_canonical(n) for n in node]
    if not isinstance(node, dict):
        return node
    rank = {k: i for i, k in enumerate(_KEYWORD_ORDER)}
    out = {}
    for key in sorted(node, key=lambda k: (rank.get(k, len(rank)), k)):
        value = node[key]
        if key == "$defs":
            out[key] = {name: _canonical(value[name]) for name in sorted(value)}
        elif key == "properties":
            out[key] = {name: _canonical(sub) for name, sub in value.items()}
        else:
            out[key] = _canonical(value)
    return out


def json_text() -> str:
    """The JSON Schema as written to ``docs/reference/case.schema.json``."""
    return json.dumps(_canonical(case_json_schema()), indent=2, ensure_ascii=False) + "\n"


# ---------------------------------------------------------------------------------------------
# The Markdown page

#: Words of a description that give the unit of a number whose name does not
_UNIT_WORDS = ("dimensionless", "count", "index", "degrees")


#: A unit opening a parenthesis of a description: ``(m)``, ``(m; null: ...)``, ``(Pa/m, > 0)``
_UNIT_IN_TEXT = re.compile(r"\((" + "|".join(re.escape(u) for _, u in UNIT_SUFFIXES)
                           + r")[;),]")


def field_unit(name: str, description: str) -> str | None:
    """The unit of a numeric field: from its name (``E_Pa``), else from its description: a
    unit opening a parenthesis (``(m)``), or the first of ``dimensionless``, ``count``
    (counts), ``index`` (a number that names a course, a unit, a draw) or ``degrees``; None if
    neither says."""
    unit = unit_of(name)
    if unit is not None:
        return unit
    found = _UNIT_IN_TEXT.search(description)
    if found:
        return found.group(1)
    for word in _UNIT_WORDS:
        if re.search(rf"\b{word}s?\b", description):
            return word
    return None


def _number(value: Any) -> str:
    """A number as a reader writes it: ``0.3``, ``1e6``, ``4.3e11``, ``9.009e-5``, ``24``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, int):
        return str(value)
    if value == SQRT3:  # the bound of the Drucker-Prager coefficients
        return "√3"
    if value == int(value) and abs(value) < 1e5:
        return str(int(value))
    if value != 0 and (abs(value) >= 1e5 or abs(value) < 1e-3):
        mantissa, exponent = f"{value:.5e}".split("e")
        return f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"
    return f"{value:.6g}"


def _value(value: Any) -> str:
    """A default as YAML writes it."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"' if value == "" else value
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    return _number(value)


def _anchor(path: str) -> str:
    """The anchor of a section's heading (GitHub's rule on the heading ``` `path` ```)."""
    return re.sub(r"[^a-z0-9 _-]", "", path.lower()).replace(" ", "-")


def _ref_name(node: dict[str, Any]) -> str | None:
    ref = node.get("$ref")
    return ref.rsplit("/", 1)[-1] if ref else None


def _range(node: dict[str, Any]) -> str:
    """``0 < x <= 1000`` from the bounds of a number."""
    low = next((f"{_number(node[k])} {op} " for k, op in (("minimum", "≤"),
                ("exclusiveMinimum", "<")) if k in node), "")
    high = next((f" {op} {_number(node[k])}" for k, op in (("maximum", "≤"),
                 ("exclusiveMaximum", "<")) if k in node), "")
    return f"{low}x{high}" if low or high else ""


def _count(node: dict[str, Any], what: str) -> str:
    low, high = node.get(f"min{what}"), node.get(f"max{what}")
    noun = "items" if what == "Items" else "characters"
    if low is not None and high is not None:
        return f"{low} to {high} {noun}"
    if high is not None:
        return f"at most {high} {noun}"
    return f"at least {low} {noun}" if low is not None else ""


class _Page:
    """The Markdown page: sections in the order a case file is written, a table each."""

    def __init__(self, schema: dict[str, Any]) -> None:
        self.schema = schema
        self.defs = schema["$defs"]
        self.lines: list[str] = []
        self.owners = {s.name: s for s in structures()}

    # what a field takes, in words ----------------------------------------------------------

    def allowed(self, node: dict[str, Any], path: str) -> str:
        """What a schema node accepts, with links to the sections of mappings."""
        if "anyOf" in node:
            options = node["anyOf"]
            texts = [self.allowed(o, path) for o in options if o.get("type") != "null"]
            text = " or ".join(texts)
            return f"null, or {text}" if len(texts) < len(options) else text
        name = _ref_name(node)
        if name is not None:
            return f"mapping: [`{path}`](#{_anchor(path)})"
        if "enum" in node:
            return "one of " + ", ".join(f"`{_value(v)}`" for v in node["enum"])
        kind = node.get("type")
        if kind in ("number", "integer"):
            text = "number" if kind == "number" else "whole number"
            bounds = _range(node)
            return f"{text}, {bounds}" if bounds else text
        if kind == "boolean":
            return "true or false"
        if kind == "string":
            size = _count(node, "Length")
            return f"text ({size})" if size else "text"
        if kind == "array":
            if "prefixItems" in node:
                items = node["prefixItems"]
                texts = {self.allowed(i, path) for i in items}
                if len(texts) == 1:
                    one = texts.pop()
                    return f"list of {len(items)}: each a {one}"
                return "list of " + ", ".join(sorted(texts))
            item = self.allowed(node.get("items", {}), f"{path}[]")
            size = _count(node, "Items")
            return f"list ({size}) of: {item}" if size else f"list of: {item}"
        return "any"

    def numeric(self, node: dict[str, Any]) -> bool:
        """Whether a node is a number, or a list of them (the fields that need a unit)."""
        if "anyOf" in node:
            return any(self.numeric(o) for o in node["anyOf"] if o.get("type") != "null") and \
                all(self.numeric(o) for o in node["anyOf"] if o.get("type") != "null")
        if node.get("type") in ("number", "integer"):
            return True
        if node.get("type") == "array":
            items = node.get("prefixItems") or [node.get("items", {})]
            return all(self.numeric(i) for i in items)
        return False

    # who reads a section -----------------------------------------------------------------

    def readers(self, path: str) -> list[str] | None:
        """The structures that read the dotted ``path`` (without ``[]``), or None if every
        structure does."""
        bare = path.replace("[]", "")
        parts = bare.split(".")
        prefixes = {".".join(parts[: i + 1]) for i in range(len(parts))}
        owners = [s.name for s in structures() if prefixes & set(s.owns)]
        return owners or None

    def readers_text(self, path: str) -> str:
        owners = self.readers(path)
        if owners is None:
            return ""
        if owners == [s.name for s in structures() if s.limit_state]:
            return "the limit states (" + ", ".join(f"`{o}`" for o in owners) + ")"
        return ", ".join(f"`{o}`" for o in owners)

    # the page ------------------------------------------------------------------------------

    def section_models(self, node: dict[str, Any], path: str) -> list[tuple[str, str]]:
        """The sections (``(path, $defs name)``) a field's node leads to: a mapping, the
        mappings of a list's items, each option of a union."""
        found = []
        name = _ref_name(node)
        if name is not None:
            found.append((path, name))
        for option in node.get("anyOf", []):
            found += self.section_models(option, path)
        if node.get("type") == "array" and "items" in node:
            found += self.section_models(node["items"], f"{path}[]")
        return found

    def table(self, properties: dict[str, Any], required: list[str], path: str) -> None:
        parent_readers = self.readers(path) if path else None
        self.lines += ["| Field | Meaning | Unit | Default | Allowed |",
                       "|---|---|---|---|---|"]
        for name, node in properties.items():
            here = f"{path}.{name}" if path else name
            meaning = node.get("description", "")
            readers = self.readers(here)
            if readers is not None and readers != parent_readers:
                meaning = f"*Read by {self.readers_text(here)} only.* {meaning}"
            unit = field_unit(name, meaning) if self.numeric(node) else None
            if name in required:
                default = "*required*"
            elif "default" in node:
                default = f"`{_value(node['default'])}`"
            elif self.section_models(node, here):
                default = "its fields' defaults"
            else:
                default = "see meaning"
            cells = [f"`{name}`", meaning, unit or "", default, self.allowed(node, here)]
            self.lines.append("| " + " | ".join(c.replace("|", "\\|").replace("\n", " ")
                                                 for c in cells) + " |")
        self.lines.append("")

    def section(self, path: str, model: str, level: int, summary: str) -> None:
        definition = self.defs[model]
        self.lines += [f"{'#' * level} `{path}`", ""]
        if summary:
            self.lines += [f"*{summary[0].upper()}{summary[1:]}.*", ""]
        parent = path.rsplit(".", 1)[0] if "." in path else ""
        readers = self.readers_text(path)
        if readers and self.readers(path) != (self.readers(parent) if parent else None):
            self.lines += [f"Read by {readers}; refused in a case of another structure.", ""]
        self.lines += [definition.get("description", ""), ""]
        props = definition.get("properties", {})
        self.table(props, definition.get("required", []), path)
        for name, node in props.items():
            for sub_path, sub_model in self.section_models(node, f"{path}.{name}"):
                self.section(sub_path, sub_model, min(level + 1, 6),
                             node.get("description", ""))

    def top_order(self) -> list[str]:
        """The top-level keys in the order a case file is written: name, description, the
        structure's section, then the common sections, the limit state's collapse rule after
        the loading."""
        keys = list(self.schema["properties"])
        names = [s.name for s in structures()]
        rest = [k for k in keys if k not in names and k not in ("name", "description")]
        if "collapse" in rest and "loading" in rest:
            rest.remove("collapse")
            rest.insert(rest.index("loading") + 1, "collapse")
        return ["name", "description", *names, *rest]

    def render(self) -> str:
        props = self.schema["properties"]
        order = self.top_order()
        self.lines += _INTRO.format(regenerate=REGENERATE,
                                    structures=self.structures_text()).split("\n")
        self.lines += ["## Top level", ""]
        self.table({k: props[k] for k in order}, [], "")
        for key in order:
            for path, model in self.section_models(props[key], key):
                self.section(path, model, 2, props[key].get("description", ""))
        return "\n".join(self.lines).rstrip() + "\n"

    def structures_text(self) -> str:
        lines = []
        for s in structures():
            reads = [p for p in s.owns if p != s.name]
            lines.append(f"- `{s.name}`: {s.description}"
                         + ("" if not s.default else " (the default: a case that names no "
                            "other structure builds a wall)")
                         + (f"; also reads {', '.join(f'`{p}`' for p in reads)}" if reads
                            else ""))
        return "\n".join(lines)


_INTRO = """\
# The case file

<!-- Made by `masonry schema --markdown` from the case model (masonry_nscd/case/); do not
edit: change the model's descriptions and run `make reference`. -->

A case file is one simulation: a YAML mapping of the sections below, in SI units (m, Pa, N, J,
s, kg; a field's unit is in its name, `E_Pa`, `rate_m_s`, or in the table). Every section and
every field is optional: the defaults are the reference study, Venzal's 1.85 x 1.20 x 0.15 m
limestone wall in shear, so `{{}}` is a valid case. A file is usually written in this order:

```yaml
# yaml-language-server: $schema=../docs/reference/case.schema.json
name: my_wall            # default: the file's stem; the name of the run's folder
description: ...
wall: {{...}}              # the structure: wall (default), arch, vault, dome, cross_vault or assembly
blocks: {{...}}            # material of the blocks
joint: {{...}}             # joint law
supports: {{...}}          # the wall's test rig
loading: {{...}}           # load stages
collapse: {{...}}          # a limit state's collapse rule
solver: {{...}}            # time step and contact solver
output: {{...}}            # what is written
```

**One structure per case.** A case builds the wall, unless it gives the section of another
structure; each structure also reads parts of the case that the others do not, and those are
refused in a case of another structure (`supports` with an arch, `collapse` with a wall):

{structures}

**Reading YAML.** Case files are read as YAML 1.2: `1e5`, `0.3e6` and `.5` are numbers, only
`true`/`false` are booleans, `null`, `~` or an empty value is null; a key given twice is an
error. A number where a whole number is expected may be written `3` or `3.0`. Anchors,
aliases and merge keys are read before any check (`vertical_stress: {{<<: *ramp, value_Pa:
0.3e6}}` takes the keys of the mapping anchored `&ramp`, which must itself be a valid part of
the case: there is no free key to park it in).

**Checking a case.** `masonry validate CASE.yaml` checks everything and exits with 2 listing
each problem (a misspelt key is named with the keys allowed there). The JSON Schema
`docs/reference/case.schema.json` lets an editor check a file as it is typed: with the YAML
language server (VS Code's YAML extension, and others), the first line of the shipped cases,
`# yaml-language-server: $schema=../docs/reference/case.schema.json`, brings completion, these
descriptions on hover, and flags misspelt keys, wrong types, values out of range and parts of
another structure. The schema checks each field on its own; the checks across fields (the
running bond's half unit, a pointed arch's radius, the joint's fracture energies, the blocks
that loads name, the files) are `masonry validate`'s. The schema asks for numbers written as
numbers, where `masonry validate` also reads numeric text (`"0.3e6"`).

**Reading the tables.** *Unit*: `dimensionless` for ratios and coefficients, `count` for
numbers of things, `index` for a number that names one (a course, a unit in a course, a
random seed). *Default*: the value when the field is left out. *Allowed*: `≤`, `<` bound the
value `x`; a list's items are described after "of". A section given as null (`scatter: null`)
is absent.

This page and the JSON Schema are made from the case model; to write them again:
`{regenerate}` (or `make reference`).
"""


def markdown_text() -> str:
    """The reference page as written to ``docs/reference/case.md``."""
    return _Page(copy.deepcopy(case_json_schema())).render()
