"""The case file's reference (``masonry schema``): the committed page and JSON Schema are the
command's, every shipped case validates against the schema, wrong cases do not (and
``masonry validate`` refuses them too), and the page names every field of the case model."""

from __future__ import annotations

import json
import re
import types
from pathlib import Path
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import jsonschema
import pytest
from pydantic import BaseModel
from typer.testing import CliRunner

from masonry_nscd.case import Case, read_yaml
from masonry_nscd.case.reference import (
    JSON_FILE,
    MARKDOWN_FILE,
    REGENERATE,
    field_unit,
    json_text,
    markdown_text,
)
from masonry_nscd.cli import app

ROOT = Path(__file__).resolve().parents[1]
CASES = sorted((ROOT / "cases").glob("*.yaml"))
MODELINE = "# yaml-language-server: $schema=../docs/reference/case.schema.json"
runner = CliRunner()


def _stale(path: str) -> str:
    return (f"{path} is not what `masonry schema` makes from the case model now; write it "
            f"again with `make reference` ({REGENERATE}) and commit it")


@pytest.fixture(scope="module")
def validator() -> jsonschema.Draft202012Validator:
    schema = json.loads((ROOT / JSON_FILE).read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


# (a) the committed files are the command's ----------------------------------------------------


def test_committed_markdown_is_the_commands():
    assert (ROOT / MARKDOWN_FILE).read_text(encoding="utf-8") == markdown_text(), \
        _stale(MARKDOWN_FILE)


def test_committed_json_schema_is_the_commands():
    assert (ROOT / JSON_FILE).read_text(encoding="utf-8") == json_text(), _stale(JSON_FILE)


@pytest.mark.parametrize("option, path", [("--markdown", MARKDOWN_FILE), ("--json", JSON_FILE)])
def test_schema_command_prints_and_writes_the_committed_text(tmp_path, option, path):
    committed = (ROOT / path).read_text(encoding="utf-8")
    printed = runner.invoke(app, ["schema", option])
    assert printed.exit_code == 0, printed.output
    assert printed.stdout == committed, _stale(path)
    target = tmp_path / "sub" / Path(path).name
    written = runner.invoke(app, ["schema", option, "-o", str(target)])
    assert written.exit_code == 0, written.output
    assert target.read_text(encoding="utf-8") == committed


@pytest.mark.parametrize("options", [[], ["--markdown", "--json"]])
def test_schema_command_needs_one_kind(options):
    result = runner.invoke(app, ["schema", *options])
    assert result.exit_code == 2 and "one of --markdown and --json" in result.output


def test_json_schema_is_draft_2020_12_and_forbids_unknown_keys_where_the_model_does(validator):
    schema = validator.schema
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    models = {model.__name__: model for _, model in _sections(Case, "")}
    assert set(schema["$defs"]) == set(models) - {"Case"}
    for name, model in models.items():
        definition = schema if name == "Case" else schema["$defs"][name]
        forbids = model.model_config.get("extra") == "forbid"
        assert (definition.get("additionalProperties") is False) == forbids, name


# (b) every shipped case validates ---------------------------------------------------------------


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_shipped_case_names_and_matches_the_schema(validator, path):
    text = path.read_text(encoding="utf-8")
    assert text.splitlines()[0] == MODELINE
    assert (path.parent / MODELINE.split("=", 1)[1]).resolve() == (ROOT / JSON_FILE).resolve()
    errors = [f"{e.json_path}: {e.message}" for e in validator.iter_errors(read_yaml(text))]
    assert not errors, errors


def test_anchors_and_merge_keys_are_read_before_the_checks(validator, tmp_path):
    text = (f"{MODELINE}\nloading:\n  gravity: &ramp {{start_s: 0.0, ramp_s: 0.1}}\n"
            "  vertical_stress:\n    <<: *ramp\n    value_Pa: 0.3e6\n")
    data = read_yaml(text)
    assert data["loading"]["vertical_stress"] == {"start_s": 0.0, "ramp_s": 0.1,
                                                  "value_Pa": 0.3e6}
    assert validator.is_valid(data)
    path = tmp_path / "merged.yaml"
    path.write_text(text, encoding="utf-8")
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 0, result.output


def test_the_defaults_validate_and_are_the_models(validator):
    """``{}`` is a valid case, and every default the schema states is the model's."""
    assert validator.is_valid({})

    def walk(model: BaseModel, definition: dict[str, Any], where: str) -> int:
        checked = 0
        for name, node in definition["properties"].items():
            value = getattr(model, name)
            if "default" in node:
                expected = list(value) if isinstance(value, tuple) else value
                assert node["default"] == expected, f"{where}{name}"
                checked += 1
            ref = node.get("$ref")
            if ref and isinstance(value, BaseModel):
                checked += walk(value, validator.schema["$defs"][ref.rsplit("/", 1)[1]],
                                f"{where}{name}.")
        return checked

    assert walk(Case(), validator.schema, "") > 100


# (c) wrong cases are flagged by the schema and by masonry validate ------------------------------

WRONG = {
    "misspelt field": ("joint:\n  mu_: 0.5\n", "mu_"),
    "value out of range": ("joint:\n  mu: 5\n", "joint.mu"),
    "wrong type": ("wall:\n  courses: eleven\n", "wall.courses"),
    "whole number with a fraction": ("wall:\n  courses: 3.5\n", "wall.courses"),
    "unknown choice": ("blocks:\n  material: granite\n", "blocks.material"),
    "true for a number": ("blocks:\n  E_Pa: true\n", "blocks.E_Pa"),
    "list item out of range": (
        "wall:\n  bond: pattern\n  pattern: [[0.001, 0.3]]\n", "wall.pattern"),
    "misspelt section": ("loadings:\n  gravity: {value_m_s2: 9.81}\n", "loadings"),
    "another structure's part": ("arch: {radius_m: 1.0}\nsupports: {clamped_courses: 1}\n",
                                 "supports"),
    "two structures": ("arch: {radius_m: 1.0}\nvault: {radius_m: 1.0}\n", "vault"),
    "a limit state's rule in a wall case": ("collapse: {end_time_s: 1.0}\n", "collapse"),
    "a joint region's value out of the joint's range": (
        "joint:\n  regions: [{joints: bed, courses: [1], mu: 5}]\n", "joint.regions[0].mu"),
}


@pytest.mark.parametrize("label", sorted(WRONG))
def test_wrong_case_is_flagged_by_the_schema_and_by_validate(validator, tmp_path, label):
    text, where = WRONG[label]
    assert not validator.is_valid(read_yaml(text)), label
    path = tmp_path / "wrong.yaml"
    path.write_text(f"{MODELINE}\n{text}", encoding="utf-8")
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert where in result.output


def test_the_schema_asks_for_numbers_written_as_numbers(validator):
    """The one place where the schema is stricter than the validation (documented on the
    page): numeric text, which the validation converts; ``3.0`` is a whole number to both."""
    assert not validator.is_valid({"blocks": {"E_Pa": "11.1e9"}})
    assert Case.model_validate({"blocks": {"E_Pa": "11.1e9"}}).blocks.E_Pa == 11.1e9
    assert validator.is_valid({"wall": {"courses": 3.0}})
    assert Case.model_validate({"wall": {"courses": 3.0}}).wall.courses == 3


# (d) the page names every field of the models ---------------------------------------------------


def _options(annotation: Any) -> list[Any]:
    """The types a field's annotation allows, Annotated and None taken off."""
    if get_origin(annotation) is Annotated:
        return _options(get_args(annotation)[0])
    if get_origin(annotation) in (Union, types.UnionType):
        return [o for a in get_args(annotation) for o in _options(a)]
    return [] if annotation is type(None) else [annotation]


def _sections(model: type[BaseModel], path: str) -> list[tuple[str, type[BaseModel]]]:
    """Every section reached from ``model`` as ``(dotted path, model)``: nested sections, the
    items of lists (``path[]``)."""
    found = [(path, model)]
    for name, info in model.model_fields.items():
        here = f"{path}.{name}" if path else name
        stack = [(here, a) for a in _options(info.annotation)]
        while stack:
            where, annotation = stack.pop(0)
            if isinstance(annotation, type) and issubclass(annotation, BaseModel):
                found += _sections(annotation, where)
            elif get_origin(annotation) is list:
                stack += [(f"{where}[]", a) for a in _options(get_args(annotation)[0])]
    return found


def _page_sections() -> dict[str, str]:
    """The page's sections by their heading's path (the top-level table: "")."""
    text = (ROOT / MARKDOWN_FILE).read_text(encoding="utf-8")
    parts = re.split(r"^#{2,6} (.+)$", text, flags=re.MULTILINE)
    sections = {}
    for heading, body in zip(parts[1::2], parts[2::2]):
        key = "" if heading == "Top level" else heading.strip("`")
        sections[key] = body
    return sections


def test_page_has_a_row_for_every_field_of_every_section():
    sections = _page_sections()
    seen = 0
    for path, model in _sections(Case, ""):
        assert path in sections, f"no section `{path}` on the page"
        for name in model.model_fields:
            assert re.search(rf"^\| `{re.escape(name)}` \|", sections[path], re.MULTILINE), \
                f"no row for {path}.{name}" if path else f"no row for {name}"
            seen += 1
    assert seen > 150


def _numeric(annotation: Any) -> bool:
    options = _options(annotation)
    if not options:
        return False
    for option in options:
        if get_origin(option) in (list, tuple):
            if not all(_numeric(a) for a in get_args(option) if a is not Ellipsis):
                return False
        elif option is bool or get_origin(option) is Literal or option not in (int, float):
            return False
    return True


def test_every_field_has_a_description_and_every_number_a_unit():
    for path, model in _sections(Case, ""):
        for name, info in model.model_fields.items():
            where = f"{path}.{name}" if path else name
            assert info.description, f"{where} has no description"
            if _numeric(info.annotation):
                assert field_unit(name, info.description), f"{where}: no unit"


def test_page_says_which_structure_reads_a_section():
    sections = _page_sections()
    assert "Read by `wall`" in sections["supports"]
    assert "Read by the limit states" in sections["collapse"]
    assert "Read by the limit states" in sections["loading.body_force"]
    assert "Read by `arch`" in sections["arch"]
    assert "Read by" not in sections["blocks"]
    top = sections[""]
    assert re.search(r"^\| `supports` \| \*Read by `wall` only\.\*", top, re.MULTILINE)
