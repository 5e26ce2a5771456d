"""`masonry plot`: PNG figures of a smoke run (curves and damage maps), and its errors."""

import subprocess
import sys

import pytest
from typer.testing import CliRunner

from masonry_nscd.cli import app

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("plots") / "run"
    res = CliRunner().invoke(app, ["run", "cases/smoke.yaml", "-o", str(out),
                                   "--set", "output.vtu=false"])
    assert res.exit_code == 0, res.output
    return out


def _is_png(path):
    data = path.read_bytes()
    return data[:8] == PNG_SIGNATURE and len(data) > 10_000


def test_plot_writes_the_curves_and_the_damage_maps(smoke_run, tmp_path):
    res = CliRunner().invoke(app, ["plot", str(smoke_run), str(smoke_run), "-o", str(tmp_path),
                                   "--at", "0,0.25", "--magnify", "200"])
    assert res.exit_code == 0, res.output
    names = sorted(p.name for p in tmp_path.iterdir())
    # the same case twice: the figures are named after the run folders
    assert names == ["damage_run_ux_0.00mm.png", "damage_run_ux_0.25mm.png",
                     "force_displacement.png"]
    assert all(_is_png(tmp_path / n) for n in names)
    assert f"wrote {tmp_path / 'force_displacement.png'}" in res.output


def test_plot_defaults_to_the_peak_and_the_end_in_the_run_folder(smoke_run):
    res = CliRunner().invoke(app, ["plot", str(smoke_run)])
    assert res.exit_code == 0, res.output
    names = sorted(p.name for p in (smoke_run / "plots").iterdir())
    assert names == ["damage_smoke_ux_0.50mm.png", "force_displacement.png"]  # peak = end


def test_plot_refuses_what_is_not_a_run_or_a_bad_option(smoke_run, tmp_path):
    res = CliRunner().invoke(app, ["plot", str(tmp_path)])
    assert res.exit_code == 2 and "not a run folder" in res.output
    res = CliRunner().invoke(app, ["plot", str(smoke_run), "--at", "1mm"])
    assert res.exit_code == 2 and "--at" in res.output


def test_help_does_not_import_matplotlib_or_scipy():
    code = ("import sys, masonry_nscd.cli; "
            "print([m for m in ('matplotlib', 'scipy', 'numpy') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def _fake_run(label, stress_Pa, material, k):
    from types import SimpleNamespace as NS
    case = NS(loading=NS(vertical_stress=NS(value_Pa=stress_Pa)), blocks=NS(material=material))
    return NS(label=label, case=case, summary={"initial_stiffness_kN_mm": k})


def test_a_sweep_s_labels_say_what_the_runs_share_once():
    from masonry_nscd.plots import _curve_labels

    runs = [_fake_run(f"seed={i}", 0.3e6, "endo3d", 104.6) for i in (1, 2)]
    labels, shared = _curve_labels(runs)
    assert labels == ["seed=1", "seed=2"]
    assert shared == "$\\sigma_N$ = 0.3 MPa, endo3d blocks, k = 105 kN/mm"
    runs.append(_fake_run("elastic", 0.3e6, "elastic", 135.6))
    labels, shared = _curve_labels(runs)
    assert labels[2] == "elastic (elastic blocks, k = 136 kN/mm)"
    assert shared == "$\\sigma_N$ = 0.3 MPa"
    labels, shared = _curve_labels(runs[:1])  # one run: everything on its own label
    assert labels == ["seed=1 ($\\sigma_N$ = 0.3 MPa, endo3d blocks, k = 105 kN/mm)"]
    assert shared == ""
