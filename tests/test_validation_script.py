"""scripts/validation.py (``make validation``) without running a simulation: its table's
arithmetic, the order of the damage maps it picks, and that every figure of
docs/validation.md is one the script redraws."""

from __future__ import annotations

import importlib.util
import math
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def validation():
    spec = importlib.util.spec_from_file_location("validation_script",
                                                  ROOT / "scripts" / "validation.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)


def test_relative_error(validation):
    row = validation.Row("b", "q", 0.1491, 0.146722764, "kinematic theorem")
    assert row.error == pytest.approx((0.1491 - 0.146722764) / 0.146722764, rel=1e-12)
    assert math.isnan(validation.Row("b", "q", "base sliding", "base sliding", "").error)
    assert math.isnan(validation.Row("b", "q", 1.0, 0.0, "").error)


def test_closed_form_references(validation):
    # the dry stone wall's overturning bound at 0.5 MPa over 1.0 x 0.2 m (100 kN)
    assert (100.0 + validation.DRY_WALL_WEIGHT_KN) * 0.5 / 0.9 == pytest.approx(57.56, abs=0.005)
    # the ground motion wall's friction limit, 0.7 (27.75 + 5.8) kN
    assert validation.GROUND_MOTION_FRICTION_KN == pytest.approx(23.485, abs=1e-9)


def test_damage_maps_in_the_order_of_their_displacement(validation, tmp_path):
    names = ["damage_w_ux_10.00mm.png", "force_displacement.png", "damage_w_ux_3.66mm.png",
             "damage_w_ux_-1.00mm.png"]
    pngs = [tmp_path / n for n in names]
    assert [p.name for p in validation.damage_maps(pngs)] == [
        "damage_w_ux_-1.00mm.png", "damage_w_ux_3.66mm.png", "damage_w_ux_10.00mm.png"]


def test_every_figure_of_the_report_is_redrawn(validation):
    report = (ROOT / "docs" / "validation.md").read_text()
    shown = set(re.findall(r"\(figures/([^)]+\.png)\)", report))
    source = (ROOT / "scripts" / "validation.py").read_text()
    drawn = set(re.findall(r"\"([A-Za-z0-9_.]+\.png)\"", source))
    drawn |= {f"damage_{s}MPa_refined_{w}.png" for s in ("0.3", "0.4", "0.5")
              for w in ("peak", "10mm")}  # named by a format string
    assert shown, "no figure found in docs/validation.md"
    assert shown <= drawn, f"figures the script does not redraw: {sorted(shown - drawn)}"


def test_the_slow_benchmarks_are_known(validation):
    assert set(validation.SLOW) <= set(validation.BENCHMARKS)
