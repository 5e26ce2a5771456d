"""More fuzzing of the case files (completes tests/test_case.py).

* Text-level edits of every shipped case (lines deleted, duplicated, swapped, cut; characters
  inserted or replaced): ``masonry validate`` and ``masonry run`` end with exit code 0 (valid)
  or 2, never a traceback; a ``run`` of an invalid file stops at the case, before any output.
* Values inside the schema's bounds: a case that validates builds its scene, or the builders
  refuse it with a ValueError that ``masonry run`` reports with exit code 2. Degenerate
  geometry such as a unit 1e-308 m high is refused by the schema's lower bounds (1 cm).
"""

from __future__ import annotations

import math
from pathlib import Path

import annotated_types as at
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel
from typer.testing import CliRunner

from masonry_nscd.case import Case, CaseError, load_case
from masonry_nscd.cli import app
from masonry_nscd.scenes import check_case

ROOT = Path(__file__).resolve().parents[1]
CASES = sorted((ROOT / "cases").glob("*.yaml"))
runner = CliRunner()
FUZZ = settings(max_examples=25, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much,
                                       HealthCheck.function_scoped_fixture])


def _clean(result, *codes: int) -> None:
    assert result.exit_code in codes, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        repr(result.exception)
    assert "Traceback" not in result.output


@st.composite
def edited_text(draw, text: str) -> str:
    """``text`` with one to three random edits of its lines or characters."""
    lines = text.splitlines(keepends=True)
    for _ in range(draw(st.integers(1, 3))):
        if not lines:
            lines = [""]
        i = draw(st.integers(0, len(lines) - 1))
        op = draw(st.sampled_from(["delete", "duplicate", "swap", "cut", "insert", "replace",
                                   "indent", "dedent"]))
        if op == "delete":
            del lines[i]
        elif op == "duplicate":
            lines.insert(i, lines[i])
        elif op == "swap":
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == "indent":
            lines[i] = " " * draw(st.integers(1, 4)) + lines[i]
        elif op == "dedent":
            lines[i] = lines[i].lstrip()
        else:
            k = draw(st.integers(0, len(lines[i])))
            piece = draw(st.one_of(st.text(max_size=8), st.sampled_from(
                [":", "-", "[", "{", "'", '"', "#", "&a", "*a", "!!python/object", "1e999",
                 "-1", "nan", ".inf", "0x10", "~", "\t", "\x00", "é"])))
            if op == "cut":
                lines[i:] = [lines[i][:k]]
            elif op == "insert":
                lines[i] = lines[i][:k] + piece + lines[i][k:]
            else:
                lines[i] = lines[i][:k] + piece + lines[i][k + len(piece):]
    return "".join(lines)


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_text_edits_of_shipped_cases(tmp_path_factory, path):
    work = tmp_path_factory.mktemp(f"edit_{path.stem}")
    text = path.read_text()

    @FUZZ
    @given(edited=edited_text(text))
    def check(edited):
        case_file = work / "case.yaml"
        case_file.write_text(edited, encoding="utf-8")
        try:
            check_case(load_case(case_file))  # the schema, then the builder's checks
            valid = True
        except CaseError as exc:
            assert exc.messages and all(isinstance(m, str) and m for m in exc.messages)
            valid = False
        result = runner.invoke(app, ["validate", str(case_file)])
        _clean(result, 0 if valid else 2)
        if not valid:
            out = work / "run"
            result = runner.invoke(app, ["run", str(case_file), "-o", str(out)])
            _clean(result, 2)
            assert not out.exists()  # stopped at the case, nothing written

    check()


# --------------------------------------------------------------------------------------------
# Valid values build a scene
# --------------------------------------------------------------------------------------------

SIZE_CAPS = {  # counts kept small so that a scene builds in a moment
    "wall.courses": 4, "wall.units_per_course": 4, "wall.contact_points_per_face": 2,
}
SKIP = {"name", "description", "solver.max_iterations", "solver.check_every",
        "output.every_steps"}


def _numeric_fields(model: type[BaseModel] = Case, prefix: str = ""):
    """(path, type, low, high, low_open, high_open) of every int/float field of the schema."""
    out = []
    for name, f in model.model_fields.items():
        ann = f.annotation
        path = prefix + name
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            out += _numeric_fields(ann, path + ".")
            continue
        if ann not in (int, float) or path in SKIP:
            continue
        lo, hi, lo_open, hi_open = -math.inf, math.inf, False, False
        for m in f.metadata:
            if isinstance(m, at.Gt):
                lo, lo_open = m.gt, True
            elif isinstance(m, at.Ge):
                lo = m.ge
            elif isinstance(m, at.Lt):
                hi, hi_open = m.lt, True
            elif isinstance(m, at.Le):
                hi = m.le
        out.append((path, ann, lo, min(hi, SIZE_CAPS.get(path, hi)), lo_open, hi_open))
    return out


FIELDS = _numeric_fields()


@st.composite
def in_bounds_edit(draw) -> str:
    """``path=value`` with a value inside the field's bounds (log-uniform over many decades
    when the range allows it, the bounds themselves included when they are)."""
    path, kind, lo, hi, lo_open, hi_open = draw(st.sampled_from(FIELDS))
    if kind is int:
        return f"{path}={draw(st.integers(int(lo), int(hi)))}"
    # no subnormal numbers (they make the shape functions divide by zero)
    cands = [st.floats(lo, hi, exclude_min=lo_open, exclude_max=hi_open, allow_subnormal=False)]
    if lo >= 0.0 and hi > 0.0:
        low = max(lo, hi * 1e-12) if lo == 0.0 else lo
        cands.append(st.floats(math.log10(low), math.log10(hi)).map(lambda x: 10.0**x)
                     .filter(lambda v: lo < v < hi or (v == lo and not lo_open)
                             or (v == hi and not hi_open)))
    if not lo_open:
        cands.append(st.just(float(lo)))
    if not hi_open:
        cands.append(st.just(float(hi)))
    return f"{path}={draw(st.one_of(cands))!r}"


@FUZZ
@given(edits=st.lists(in_bounds_edit(), min_size=1, max_size=3),
       material=st.sampled_from(["elastic", "endo3d", "rigid"]))
def test_a_valid_case_builds_its_scene(edits, material):
    from masonry_nscd.scenes import build_scene

    try:
        case = load_case(ROOT / "cases" / "smoke.yaml", [f"blocks.material={material}", *edits])
    except CaseError:
        assume(False)
    try:
        integ = build_scene(case).integrator()
    except ValueError as exc:  # run_case turns it into exit code 2 with this message
        assert str(exc)
    else:
        assert integ.sys.ndof > 0


@pytest.mark.parametrize("edit, bound", [("wall.unit_height_m=1e-308", "0.01 <= value"),
                                         ("blocks.density_kg_m3=1e-30", "100 <= value"),
                                         ("joint.K_I_spring_Pa_m=1e-3", "1e+06 <= value"),
                                         ("solver.time_step_s=1e-300", "1e-06 <= value")])
def test_degenerate_values_are_refused_with_their_bound(tmp_path, edit, bound):
    """Values that once passed a "> 0" bound and failed inside the solver (a unit 1e-308 m
    high, a density of 1e-30 kg/m^3): exit code 2, the field and its range named."""
    res = runner.invoke(app, ["run", str(ROOT / "cases" / "smoke.yaml"), "-o", str(tmp_path / "r"),
                              "--set", edit])
    _clean(res, 2)
    assert "invalid case" in res.output and edit.split("=")[0] in res.output
    assert bound in res.output
    assert not (tmp_path / "r").exists()
