"""Rigid-block limit analysis (``masonry limit``, ``masonry_nscd/limit/``) against physics and
independent calculations written here: the tilting table, the four-hinge mechanism of an arch
by the kinematic theorem (every four-hinge mechanism of the voussoirs enumerated), the minimum
thickness of the same arch by a thrust line searched joint by joint, and the NSCD collapse
multipliers of the shipped cases (docs/validation.md)."""

from __future__ import annotations

import json
import math
from itertools import combinations, pairwise
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import linprog
from typer.testing import CliRunner

from masonry_nscd.case import load_case
from masonry_nscd.cli import app
from masonry_nscd.limit import friction, mechanism, path, statics
from masonry_nscd.limit.analysis import analyse, format_result
from masonry_nscd.limit.lp import elastic_state, solve_limit, solve_non_associative
from masonry_nscd.limit.path import follow_load
from masonry_nscd.limit.statics import rigid_model
from masonry_nscd.limit.thickness import threshold
from masonry_nscd.post.limit import describe_hinges
from masonry_nscd.scenes import build_scene
from masonry_nscd.scenes.small import tilting_block

CASES = Path(__file__).resolve().parents[1] / "cases"
ARCH = CASES / "arch_semicircular.yaml"


# --- the tilting table ----------------------------------------------------------------------

@pytest.mark.parametrize("width, height, mu", [(0.1, 0.4, 0.6), (0.1, 0.4, 0.2),
                                               (0.3, 0.4, 0.5)])
@pytest.mark.parametrize("facets", [3, 4, 8, 16])
def test_block_on_a_tilting_plane(width, height, mu, facets):
    """A rigid block b x h on a fixed base, a horizontal multiplier of its weight: it topples
    at b/h when b/h < mu, it slides at mu otherwise, the friction within the pyramid's bound
    ``mu cos(pi/k) <= lambda <= mu`` (exact with 4 facets: vertices on +-t, +-s)."""
    m = rigid_model(tilting_block(width=width, height=height, mu=mu))
    sol = solve_limit(m, facets)
    assert sol.status == "optimal"
    lam = sol.multiplier
    v = sol.velocity[0]  # the block: v_x, v_y, v_z, omega_x, omega_y, omega_z about its centre
    if width / height < mu * friction.inscribed_fraction(facets):
        assert lam == pytest.approx(width / height, rel=1e-7)
        # toppling about the toe (x = b/2 from the centre, y = -h/2): v = omega x (c - toe)
        assert v[5] < 0.0
        assert v[0] == pytest.approx(-v[5] * height / 2, rel=1e-6)
        assert v[1] == pytest.approx(-v[5] * width / 2, rel=1e-6)
        kinds = [j["kind"] for j in mechanism.joints(m, sol.point_velocity,
                                                     {"groups": ["base"]})]
        assert kinds == ["hinge"]
    else:
        assert mu * friction.inscribed_fraction(facets) * (1 - 1e-7) <= lam <= mu * (1 + 1e-7)
        if facets == 4:
            assert lam == pytest.approx(mu, rel=1e-7)
        assert abs(v[5]) < 1e-6 * abs(v[0])
        kinds = [j["kind"] for j in mechanism.joints(m, sol.point_velocity,
                                                     {"groups": ["base"]})]
        assert kinds == ["sliding"]


def test_cone_error_bound():
    """The inscribed polygon of k facets reaches cos(pi/k) of the cone's radius."""
    for k in (3, 4, 8, 16, 32):
        n = friction.facet_normals(k)
        # the facet's distance from the centre (a vertex at angle 0 is on the unit circle)
        assert float(n[0] @ [1.0, 0.0]) == pytest.approx(math.cos(math.pi / k))
        assert friction.cone_error_bound(k) == pytest.approx(1.0 - math.cos(math.pi / k))
    assert friction.cone_error_bound(16) < 0.02


# --- the arch: independent calculations ------------------------------------------------------

def chord_voussoirs(n: int, radius: float, thickness: float):
    """The semicircular arch of ``n`` voussoirs on radial joints, each a trapezoid on the
    chords: joint ends (n + 1, 2) at the intrados and extrados, joint normals towards higher
    numbers, and per voussoir its area (m^2) and centroid (m)."""
    theta = math.pi * np.arange(n + 1) / n
    u = np.stack([-np.cos(theta), np.sin(theta)], axis=1)
    a, b = (radius - thickness / 2) * u, (radius + thickness / 2) * u
    normal = np.stack([np.sin(theta), np.cos(theta)], axis=1)
    area, centroid = np.zeros(n), np.zeros((n, 2))
    for k in range(n):
        poly = np.array([a[k], a[k + 1], b[k + 1], b[k]])
        x, y = poly[:, 0], poly[:, 1]
        cross = x * np.roll(y, -1) - np.roll(x, -1) * y
        A = 0.5 * cross.sum()
        area[k] = abs(A)
        centroid[k] = [((x + np.roll(x, -1)) * cross).sum() / (6 * A),
                       ((y + np.roll(y, -1)) * cross).sum() / (6 * A)]
    return a, b, normal, area, centroid


def ring_voussoirs(n: int, radius: float, thickness: float, staggered: bool):
    """A ring of the barrel vault (scenes/vault.py): the arch of ``2 n`` chord half voussoirs,
    taken two by two (joints at every other half joint), or, ``staggered``, a half voussoir
    at each springing and whole ones between (joints at the odd half joints); the arrays of
    :func:`chord_voussoirs` for those voussoirs."""
    a, b, normal, area, centroid = chord_voussoirs(2 * n, radius, thickness)
    joints = ([0, *range(1, 2 * n, 2), 2 * n] if staggered else list(range(0, 2 * n + 1, 2)))
    W = np.array([area[lo:hi].sum() for lo, hi in pairwise(joints)])
    c = np.array([(area[lo:hi, None] * centroid[lo:hi]).sum(axis=0) / area[lo:hi].sum()
                  for lo, hi in pairwise(joints)])
    return a[joints], b[joints], normal[joints], W, c


def four_hinge_multiplier(n: int, radius: float, thickness: float,
                          point_load: int | None = None, geometry=None):
    """The kinematic theorem: the least horizontal multiplier of the weight over every
    admissible four-hinge mechanism (hinges at joints i < j < k < l, each at the intrados or
    the extrados, the three bodies between them turning about A, the intersection of AB and
    DC, and D; hinges must open). With ``point_load`` (a voussoir's 0-based index), the least
    downward force at the middle of its extrados chord instead, per unit of the weight of a
    unit of area. ``geometry``: the arrays of :func:`chord_voussoirs` for other voussoirs
    (``n`` is then their number). Returns (lambda, ((joint, face) * 4))."""
    a, b, normal, W, c = geometry or chord_voussoirs(n, radius, thickness)
    n = len(W)
    # prefix sums per voussoir: W, W c_x, W c_y
    S = np.vstack([np.zeros(3), np.cumsum(np.column_stack([W, W * c[:, 0], W * c[:, 1]]),
                                          axis=0)])

    def seg(lo, hi):  # voussoirs between joints lo and hi (voussoirs lo+1..hi, 0-based lo..hi-1)
        return S[hi] - S[lo]

    def cross2(p, q):
        return p[0] * q[1] - p[1] * q[0]

    best = (math.inf, None)
    ends = {0: a, 1: b}
    for i, j, k, l in combinations(range(n + 1), 4):
        for faces in ((0, 1, 0, 1), (1, 0, 1, 0)):
            A, B, C, D = (ends[f][q] for f, q in zip(faces, (i, j, k, l)))
            # the instant centre of the middle body: AB meets DC
            d1, d2 = B - A, C - D
            den = cross2(d1, d2)
            if abs(den) < 1e-12:
                continue
            O = A + d1 * cross2(D - A, d2) / den
            w1 = 1.0
            w2 = w1 * float((B - A) @ (B - O)) / float((B - O) @ (B - O))
            w3 = w2 * float((C - O) @ (C - D)) / float((C - D) @ (C - D))
            bodies = ((w1, A, seg(i, j)), (w2, O, seg(j, k)), (w3, D, seg(k, l)))
            # power of the weight (0, -W) and of the horizontal force (W, 0), per unit g:
            # v = w (-(y - O_y), x - O_x)
            dead = sum(-w * (s[1] - P[0] * s[0]) for w, P, s in bodies)
            if point_load is None:
                live = sum(-w * (s[2] - P[1] * s[0]) for w, P, s in bodies)
            else:  # the force (0, -1) at Q, carried by the body that holds the voussoir
                Q = 0.5 * (b[point_load] + b[point_load + 1])
                live = 0.0
                for (w, P, _), lo, hi in zip(bodies, (i, j, k), (j, k, l)):
                    if lo <= point_load < hi:
                        live = -w * (Q[0] - P[0])
            if abs(live) < 1e-15:
                continue
            sign = 1.0 if live > 0 else -1.0
            omegas = [0.0, sign * w1, sign * w2, sign * w3, 0.0]
            ok = True
            for h, (q, f) in enumerate(zip((i, j, k, l), faces)):
                P, Q = ends[f][q], ends[1 - f][q]
                dw = omegas[h + 1] - omegas[h]  # upper body's rotation relative to the lower
                rel = dw * np.array([-(Q - P)[1], (Q - P)[0]])
                if rel @ normal[q] < -1e-12:
                    ok = False
                    break
            lam = -dead / live
            if ok and 0.0 < lam < best[0]:
                best = (lam, tuple((q, ("intrados", "extrados")[f])
                                   for q, f in zip((i, j, k, l), faces)))
    return best


def statics_thrust_line(n: int, radius: float, thickness: float, lam: float, hinges):
    """The line of thrust of the four-hinge mechanism by statics alone: the force ``S`` that
    the voussoirs below the first hinge's joint i press on those above, through its hinge
    point, is fixed by the moments about the second and third hinges of the voussoirs
    between; the force across any joint j is then ``S`` plus the loads of the voussoirs
    between i and j, and its moment about the origin fixes where it crosses the joint.
    Returns per joint the eccentricity over half the joint (1 at the extrados)."""
    a, b, _, W, c = chord_voussoirs(n, radius, thickness)
    ends = {"intrados": a, "extrados": b}
    (i, fi), (j, fj), (k, fk) = hinges[:3]
    P, Q, R = ends[fi][i], ends[fj][j], ends[fk][k]
    L = np.column_stack([lam * W, -W])  # the loads of the voussoirs, (lambda W, -W)
    m = c[:, 0] * L[:, 1] - c[:, 1] * L[:, 0]  # their moments about the origin

    def rows(lo, hi, O):  # moment about O of S at P and of voussoirs lo..hi-1: M0 + S x ...
        r = P - O
        const = ((c[lo:hi] - O)[:, 0] * L[lo:hi, 1] - (c[lo:hi] - O)[:, 1] * L[lo:hi, 0]).sum()
        return [-r[1], r[0]], -const

    (r1, c1), (r2, c2) = rows(i, j, Q), rows(i, k, R)
    S_i = np.linalg.solve(np.array([r1, r2]), np.array([c1, c2]))
    M_i = P[0] * S_i[1] - P[1] * S_i[0]
    out = []
    for q in range(n + 1):
        lo, hi, sign = (i, q, 1.0) if q >= i else (q, i, -1.0)
        S = S_i + sign * L[lo:hi].sum(axis=0)
        M = M_i + sign * m[lo:hi].sum()
        d = b[q] - a[q]
        s = (M - (a[q][0] * S[1] - a[q][1] * S[0])) / (d[0] * S[1] - d[1] * S[0])
        out.append(2.0 * s - 1.0)
    return np.array(out)


def test_thrust_line_of_the_arch_at_collapse():
    """The line of thrust of the shipped arch at its horizontal collapse multiplier: the
    eccentricity of every joint's resultant is that of the statics of the four-hinge
    mechanism (the kinematic theorem's multiplier and hinges), within the joint everywhere
    and on the hinged face at the four hinges."""
    result = analyse(load_case(ARCH))
    lam, hinges = four_hinge_multiplier(24, 1.0, 0.15)
    expected = statics_thrust_line(24, 1.0, 0.15, lam, hinges)
    line = result.record["thrust_line"]
    assert [r["joint"] for r in line] == list(range(25))
    got = np.array([r["relative_eccentricity"] for r in line])
    assert got == pytest.approx(expected, abs=1e-6)
    assert np.all(np.abs(got) <= 1.0 + 1e-7)
    for joint, side in hinges:
        assert got[joint] == pytest.approx(1.0 if side == "extrados" else -1.0, abs=1e-6)


def test_collapse_load_of_a_point_load():
    """A downward force on the extrados of voussoir 7 of the shipped arch: the programme's
    force is the kinematic theorem's least over the four-hinge mechanisms, with its hinges."""
    sets = ["loading.body_force.rate_per_s=0",
            "loading.point_load={block: voussoir 7, rate_N_s: 200}"]
    result = analyse(load_case(ARCH, sets))
    per_area = 2000.0 * 9.81 * 0.25  # N per m^2 of the chord trapezoids (density, g, depth)
    expected, hinges = four_hinge_multiplier(24, 1.0, 0.15, point_load=6)
    assert result.record["multiplier"]["name"] == "point_load_N"
    assert result.solution.multiplier == pytest.approx(expected * per_area, rel=1e-6)
    assert sorted((h["joint"], h["side"]) for h in result.record["hinges"]) == sorted(hinges)


def test_deformable_blocks_are_taken_as_the_rigid_bodies_of_their_meshes():
    """Elastic voussoirs of 2 x 2 x 1 hexahedra: the same multiplier and hinges as rigid ones
    (their nodal weights reduced to the rigid body of the mesh)."""
    rigid = analyse(load_case(ARCH))
    elastic = analyse(load_case(ARCH, ["blocks.material=elastic",
                                       "arch.elements_per_voussoir=[2,2,1]"]))
    assert elastic.solution.multiplier == pytest.approx(rigid.solution.multiplier, rel=1e-6)
    assert [h["joint"] for h in elastic.record["hinges"]] == \
        [h["joint"] for h in rigid.record["hinges"]]


def thrust_line_stands(n: int, radius: float, thickness: float) -> bool:
    """A symmetric thrust line lies within every joint of the arch under its own weight: the
    crown joint (vertical, n even) carries a horizontal thrust H at the height y0, and the
    resultant across each joint j of the right half, from the moment about a point p of the
    joint of the voussoirs between the crown and j, M(p) = -H y0 + H p_y - sum W (c_x - p_x),
    crosses the joint between its ends: M(intrados) <= 0 <= M(extrados). Linear in (H, H y0):
    a feasibility problem in two unknowns."""
    a, b, _, W, c = chord_voussoirs(n, radius, thickness)
    rows, rhs = [], []
    for j in range(n // 2, n + 1):
        seg = slice(n // 2, j)
        sw, swx = W[seg].sum(), (W[seg] * c[seg, 0]).sum()
        for p, sign in ((a[j], 1.0), (b[j], -1.0)):
            # sign * M(p) <= 0 with M = -m + p_y H - swx + p_x sw, unknowns (H, m = H y0)
            rows.append([sign * p[1], -sign])
            rhs.append(sign * (swx - p[0] * sw))
    res = linprog(np.zeros(2), A_ub=np.array(rows), b_ub=np.array(rhs),
                  bounds=[(0, None), (None, None)], method="highs")
    return res.status == 0


def test_horizontal_multiplier_of_the_arch_and_its_four_hinges():
    """The shipped arch (24 voussoirs, t/R = 0.15): the multiplier of the static programme is
    the least of the kinematic theorem's over every four-hinge mechanism, with the same four
    hinges; the virtual work of the mechanism balances."""
    case = load_case(ARCH)
    result = analyse(case)
    lam = result.solution.multiplier
    expected, hinges = four_hinge_multiplier(24, 1.0, 0.15)
    assert lam == pytest.approx(expected, rel=1e-6)
    found = [(h["joint"], h["side"]) for h in result.record["hinges"]]
    assert sorted(found) == sorted(hinges)
    assert result.record["mechanism"] == "four-hinge"
    m, v = result.model, result.solution.velocity.ravel()
    assert lam * (m.live @ v) + m.dead @ v == pytest.approx(0.0, abs=1e-9 * abs(m.dead @ v))


@pytest.mark.parametrize("load", ["body_force", "point_load"])
def test_a_held_load_is_analysed_as_the_load_it_holds(load):
    """A run's hold (``hold_s``) stops the growth in time; the analysis of the held case is
    that of the growing load all the same: the kinematic theorem's multiplier of the arch, for
    the body force and for a force on voussoir 7."""
    sets = [] if load == "body_force" else [
        "loading.body_force.rate_per_s=0",
        "loading.point_load={block: voussoir 7, rate_N_s: 200}"]
    held = analyse(load_case(ARCH, [*sets, f"loading.{load}.hold_s=1.0"]))
    per_area = 2000.0 * 9.81 * 0.25  # N per m^2 of the chord trapezoids (density, g, depth)
    expected, _ = (four_hinge_multiplier(24, 1.0, 0.15) if load == "body_force" else
                   four_hinge_multiplier(24, 1.0, 0.15, point_load=6))
    scale = 1.0 if load == "body_force" else per_area
    assert held.solution.multiplier == pytest.approx(expected * scale, rel=1e-6)


def test_minimum_thickness_of_the_arch():
    """The minimum thickness of the shipped arch's 24 voussoirs by bisection on the static
    programme (``masonry threshold --method limit``) is that of the thrust line within 0.1 %,
    and close to the Couplet-Heyman value of a continuous arch (0.1075)."""
    lo, hi = 0.09, 0.13
    assert thrust_line_stands(24, 1.0, hi) and not thrust_line_stands(24, 1.0, lo)
    while hi - lo > 1e-7:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if thrust_line_stands(24, 1.0, mid) else (mid, hi)
    independent = 0.5 * (lo + hi)
    out = threshold(lambda t: load_case(ARCH, [f"arch.thickness_m={t!r}", "joint.mu=2.0"]),
                    (0.09, 0.13), rtol=1e-5)
    assert out["value"] == pytest.approx(independent, rel=1e-3)
    assert out["value"] == pytest.approx(0.1075, rel=0.01)
    assert out["time_s"] < 10.0


# --- the shipped cases against NSCD ----------------------------------------------------------

#: The NSCD collapse multipliers at the onset of the mechanism (docs/validation.md, rigid
#: blocks, stiff dry joints, lambda growing at 0.05 /s; the pier at 0.1 /s).
NSCD = {"arch_semicircular": 0.1491, "pier_arches": 0.3816}


@pytest.mark.parametrize("name", sorted(NSCD))
def test_shipped_cases_against_nscd(name):
    """The arch and the pier with its half arches: the limit multiplier lies within 2 % below
    the NSCD onset (the run is dynamic: its onset, detected at a speed, comes after the static
    limit, the more the faster the load grows; its joints are stiff springs)."""
    result = analyse(load_case(CASES / f"{name}.yaml"))
    lam = result.solution.multiplier
    assert 0.0 < (NSCD[name] - lam) / NSCD[name] < 0.02
    assert result.record["hinges"]


def test_the_report_names_twelve_hinges_and_counts_the_others():
    """The cross vault's mechanism has more hinges than a line can name: ``masonry limit``
    prints the first twelve and how many more ``limit.json`` lists (all of them)."""
    result = analyse(load_case(CASES / "cross_vault.yaml"))
    hinges = result.record["hinges"]
    assert len(hinges) > 12
    line = next(x for x in format_result(result.record) if x.startswith("mechanism:"))
    assert line.count(" / ") == 12
    assert f"; {len(hinges) - 12} more (limit.json lists every hinge)" in line
    assert describe_hinges(hinges[:3], "limit.json").count(" / ") == 3  # all named, no count
    assert "more" not in describe_hinges(hinges[:12], "limit.json")


def test_non_associative_iteration_keeps_a_hinge_mechanism():
    """Where nothing slides the iteration of fixed friction capacities keeps the associative
    multiplier (the arch), and it converges."""
    m = rigid_model(build_scene(load_case(ARCH)))
    sol, record = solve_non_associative(m)
    assert record["converged"]
    assert sol.multiplier == pytest.approx(record["associative"], rel=1e-6)


def test_tension_raises_the_multiplier():
    """With the cohesive law's tensile strength and cohesion the arch carries more."""
    sets = ["joint.law=fczm", "joint.d_coh_initial=0.5"]
    case = load_case(ARCH, sets)
    dry = analyse(case).solution.multiplier
    glued = analyse(case, tension=True).solution.multiplier
    assert glued > dry


def test_the_command_writes_its_files(tmp_path):
    """``masonry limit``: limit.json with the multiplier, its kind and the mechanism, the VTU
    files, the joint forces and the picture; an unknown flow is refused with exit 2."""
    out = tmp_path / "arch"
    r = CliRunner().invoke(app, ["limit", str(ARCH), "-o", str(out)])
    assert r.exit_code == 0, r.output
    rec = json.loads((out / "limit.json").read_text())
    assert rec["multiplier"]["name"] == "lambda"
    assert rec["multiplier"]["kind"].startswith("associative")
    assert rec["friction"]["facets"] == friction.DEFAULT_FACETS
    assert len(rec["hinges"]) == 4
    for name in ("mechanism.vtu", "joint_forces.csv", "joint_forces.vtu", "thrust_line.csv",
                 "mechanism.png"):
        assert (out / name).stat().st_size > 0
    rows = (out / "joint_forces.csv").read_text().splitlines()
    assert len(rows) == 1 + rec["counts"]["points"]
    r = CliRunner().invoke(app, ["limit", str(ARCH), "-o", str(tmp_path / "x"),
                                 "--flow", "sideways"])
    assert r.exit_code == 2
    r = CliRunner().invoke(app, ["limit", str(ARCH), "-o", str(tmp_path / "y"),
                                 "--flow", "non-associative", "--start", "sideways"])
    assert r.exit_code == 2


def test_the_dome_rests_on_its_ring_only_through_its_bed():
    """The shipped dome on its fixed ring: the lowest course touches the ring on its bed faces
    only (every base point's normal vertical; the faces between the ring's hexahedra are
    inside the ring, not joints level with the head joints above them), so the whole dome
    sliding on the ring, lifted by mu times its slip, is a mechanism of the associative
    model with lambda = mu: the kinematic theorem bounds the multiplier by mu."""
    case = load_case(CASES / "dome_hemispherical.yaml")
    scene = build_scene(case)
    base = scene.groups.index("base")
    normals = np.array([p.frame[0] for p in scene.points if p.group == base])
    assert len(normals) and np.allclose(np.abs(normals[:, 1]), 1.0, atol=1e-12)
    result = analyse(case)
    assert 0.0 < result.solution.multiplier <= case.joint.mu * (1.0 + 1e-6)


def test_non_associative_sliding_block():
    """A block that slides on its base (mu below b/h), on the exact cone: lifted by mu times
    its slip against its weight (associative) or held by the friction mu W (non-associative),
    it slides at lambda = mu either way, and the proximal iteration converges on it."""
    m = rigid_model(tilting_block(width=0.3, height=0.4, mu=0.5))
    sol, record = solve_non_associative(m)
    assert record["converged"]
    assert record["associative"] == pytest.approx(0.5, rel=1e-6)
    assert sol.multiplier == pytest.approx(0.5, rel=1e-6)


def test_the_dry_stone_wall_pushed_by_its_beam():
    """The dry stone wall with rigid units, driven by its top beam: the push is the growing
    load (a horizontal force on the beam, N), and by the kinematic theorem it is at most the
    force that turns the wall above its first course (glued to the ground beam) as one piece
    about its toe: (N + W) x 0.5 m / 0.9 m, N the beam's 100 kN and W the 8 courses' weight
    (1.0 x 0.1 x 0.2 m each at 2300 kg/m^3), the beam's reference point 0.9 m above the toe;
    a wall that steps and slides within carries less."""
    case = load_case(CASES / "dry_stone_wall.yaml", ["blocks.material=rigid"])
    result = analyse(case)
    m = result.model
    assert m.factor == "push_force_N"
    beam = m.names.index("upper beam")
    assert m.dead[6 * beam + 1] == pytest.approx(-100e3)
    W = 8 * 1.0 * 0.1 * 0.2 * 2300.0 * 9.81
    bound = (100e3 + W) * 0.5 / (m.reference[beam, 1] - 0.1)
    assert 0.0 < result.solution.multiplier <= bound * (1 + 1e-9)


def test_the_two_solvers_agree_on_the_pyramid():
    """The same pyramid programme (8 facets) on the sliding block and the arch: Clarabel's
    interior point and HiGHS's interior point with crossover find the same multiplier."""
    for m in (rigid_model(tilting_block(width=0.3, height=0.4, mu=0.5)),
              rigid_model(build_scene(load_case(ARCH)))):
        a = solve_limit(m, 8, solver="clarabel").multiplier
        b = solve_limit(m, 8, solver="highs").multiplier
        assert a == pytest.approx(b, rel=1e-7)


@pytest.mark.parametrize("ratio", [0.6, 0.8, 2.0])
def test_compressive_strength_of_a_toppling_block(ratio):
    """The block b x h x d (0.1 x 0.4 x 0.15 m) on its four base corners (each a quarter of
    the base's area A), with the compression of a point bounded by f_c times its area: it
    topples about its toe, whose two points carry N_toe = min(W, f_c A / 2), the heel the rest;
    the moment about the base's middle, lambda W h / 2 = (N_toe - N_heel) b / 2, gives
    lambda = (2 N_toe - W) b / (W h) (b/h when the toe is strong enough: ratio >= 1, with
    f_c = ratio x 2 W / A)."""
    b, h, d = 0.1, 0.4, 0.15
    W = 2000.0 * 9.81 * b * h * d
    A = b * d
    f_c = ratio * 2.0 * W / A
    m = rigid_model(tilting_block(width=b, height=h, depth=d, mu=2.0))
    n_toe = min(W, f_c * A / 2.0)
    expected = (2.0 * n_toe - W) * b / (W * h)
    for solver, facets in (("clarabel", 0), ("highs", 8)):
        sol = solve_limit(m, facets, solver=solver, compressive_Pa=f_c)
        assert sol.multiplier == pytest.approx(expected, rel=1e-6)


def test_bench_limit_prints_a_row_per_value():
    """``masonry bench-limit``: one row per value of the scaled parameter, with its blocks
    (the arch's voussoirs) and its multiplier; a value the case refuses exits with 2."""
    r = CliRunner().invoke(app, ["bench-limit", str(ARCH), "--param", "arch.voussoirs",
                                 "--values", "12,24"])
    assert r.exit_code == 0, r.output
    rows = [line.split() for line in r.output.splitlines()[2:]]
    assert [(float(v[0]), int(v[1])) for v in rows] == [(12.0, 12), (24.0, 24)]
    assert float(rows[1][3]) == pytest.approx(0.146723, rel=1e-4)  # printed to 5 digits
    r = CliRunner().invoke(app, ["bench-limit", str(ARCH), "--param", "arch.voussoirs",
                                 "--values", "-3"])
    assert r.exit_code == 2


# --- the non-associative iteration's start -------------------------------------------------

def test_a_block_wedged_between_walls_slides_on_its_base():
    """A block 0.2 x 0.1 x 0.2 m touching two fixed walls (on its faces normal to x) without
    pressure, pushed along the walls (z) by lambda times its weight, mu = 0.5. Rigid blocks
    admit a self-stress (the block pressed between the walls) that buys any friction on the
    walls: the associative programme is unbounded. Loaded from rest, nothing presses the walls:
    their friction is zero and the block slides on its base at lambda = mu, the least
    non-associative collapse load (a state with the walls' normal force zero carries no more,
    and any normal force there only adds friction). The elastic state under gravity puts the
    whole weight on the base (to the interior point's slack, 1e-5), the iteration from it ends
    at mu; from the associative solution it has no start."""
    mu, W = 0.5, 2000.0 * 0.2 * 0.1 * 0.2 * 9.81
    m = rigid_model(tilting_block(width=0.2, height=0.1, depth=0.2, mu=mu, walls=True,
                                  direction=(0.0, 0.0, 1.0)))
    side = m.group == 1
    assert side.sum() == 8 and (~side).sum() == 4
    assert solve_limit(m).status == "unbounded"
    forces, _, record = elastic_state(m)
    assert record["converged"]
    # to the interior point's slack
    assert forces[~side, 0].sum() == pytest.approx(W, rel=1e-5)
    assert np.abs(forces[side]).max() < 1e-5 * W
    sol, rec = solve_non_associative(m, start="elastic")
    assert rec["converged"]
    assert sol.multiplier == pytest.approx(mu, rel=1e-6)
    assert sol.forces[side, 0].max() < 1e-4 * W  # one step's slack (the last, unpenalised)
    kinds = {j["group"]: j["kind"] for j in mechanism.joints(
        m, sol.point_velocity, {"groups": ["base", "side"]})}
    assert kinds["base"] == "sliding"
    sol, rec = solve_non_associative(m, start="associative")
    assert sol.multiplier is None and not rec["multipliers"]


def test_the_barrel_vault_collapses_as_its_weakest_ring():
    """The shipped barrel vault (four rings side by side, the even ones staggered), high
    friction: under loads in their plane nothing presses the rings against each other, so in
    the state loaded from rest the faces between them carry nothing and each ring is an arch
    on its own. The non-associative iteration from the elastic state ends at the least
    multiplier of the rings, the staggered ring's, by the kinematic theorem over every
    four-hinge mechanism of its voussoirs (0.145918); the faces between the rings carry no
    normal force in the elastic state (to the interior point's slack, 1e-5). The associative
    programme presses the rings together and holds them by friction (far above); from its
    solution the iteration drains that self-stress step by step (it carries nothing the
    fixed capacities need, and the normal forces' penalty takes it out) and ends within 1 %."""
    case = load_case(CASES / "vault_barrel.yaml", ["joint.mu=2.0"])
    scene = build_scene(case)
    m = rigid_model(scene)
    rings = m.group == scene.groups.index("ring")
    expected = min(four_hinge_multiplier(0, 1.0, 0.15,
                                         geometry=ring_voussoirs(24, 1.0, 0.15, staggered))[0]
                   for staggered in (False, True))
    forces, _, record = elastic_state(m)
    assert record["converged"]
    assert forces[rings, 0].max() < 1e-5 * forces[:, 0].max()
    sol, rec = solve_non_associative(m, start="elastic")
    assert rec["converged"]
    assert sol.multiplier == pytest.approx(expected, rel=1e-5)
    assert solve_limit(m).multiplier > 1.5 * expected
    other, rec = solve_non_associative(m, start="associative")
    assert rec["converged"]
    assert other.multiplier == pytest.approx(expected, rel=1e-2)


def test_the_iteration_from_the_state_of_an_nscd_run(tmp_path):
    """The same vault run by NSCD under its dead loads alone (gravity, then 0.2 s at rest):
    the normal forces read from the run (traction times area) carry the vault's weight on its
    springings (horizontal joints: the sum of their normal forces is the weight), the faces
    between the rings carry none, and the iteration started from them ends at the weakest
    ring's multiplier, as from the elastic state. The command refuses a run of another case
    and ``--start run`` without its folder, once each, exit 2, nothing written."""
    from masonry_nscd.limit.analysis import run_normal_forces
    from masonry_nscd.run import run_case

    settings = ["joint.mu=2.0"]
    vault = CASES / "vault_barrel.yaml"
    run = tmp_path / "run"
    run_case(load_case(vault, [*settings, "loading.body_force.start_s=10",
                               "collapse.end_time_s=0.3", "output.vtu=false"]),
             run, echo=lambda _m: None)
    case = load_case(vault, settings)
    scene = build_scene(case)
    m = rigid_model(scene)
    N, origin = run_normal_forces(m, run)
    assert origin["time_s"] == pytest.approx(0.3)
    weight = 9.81 * sum(b.mass for i, b in enumerate(scene.bodies) if not m.support[i])
    springing = m.support[m.pair].any(axis=1)
    assert np.abs(m.frame[springing, 0, 1]).min() == pytest.approx(1.0)
    assert N[springing].sum() == pytest.approx(weight, rel=1e-4)
    assert N[m.group == scene.groups.index("ring")].max() < 1e-5 * N.max()
    expected = min(four_hinge_multiplier(0, 1.0, 0.15,
                                         geometry=ring_voussoirs(24, 1.0, 0.15, staggered))[0]
                   for staggered in (False, True))
    sol, rec = solve_non_associative(m, start="run", start_normal=N)
    assert rec["converged"]
    assert sol.multiplier == pytest.approx(expected, rel=1e-5)
    runner = CliRunner()
    for args, word in (([str(ARCH), "--start", "run", "--run", str(run)], "contact points"),
                       ([str(vault), "--start", "run"], "--run OUTDIR")):
        res = runner.invoke(app, ["limit", *args, "--flow", "non-associative",
                                  "-o", str(tmp_path / "out")])
        assert res.exit_code == 2
        assert res.output.count("error") == 1 and word in res.output
        assert not (tmp_path / "out").exists()

# --- the load followed from rest (--method load-path) -----------------------------------------

def test_the_load_path_point_law_by_hand_and_by_differences():
    """One point of each kind against the law written out (k_n = k_t = 1e9 N/m, mu = 0.5):
    open, sticking, sliding and glued; then the tangent of every kind against central
    differences of the forces."""
    kn = kt = np.full(4, 1e9)
    mu = np.full(4, 0.5)
    glued = np.array([False, False, False, True])
    g = np.array([[1e-4, 3e-4, 0.0],     # open
                  [-1e-3, 2e-4, 0.0],    # closed, |F*| = 2e5 N <= mu N = 5e5 N: sticks
                  [-1e-3, 2e-3, 0.0],    # |F*| = 2e6 N > 5e5 N: slides back to the cone
                  [1e-4, 3e-4, 0.0]])    # glued: a spring in tension too
    slip = np.zeros((4, 2))
    f, D, after, closed, sliding = path.joint_forces(g, slip, kn, kt, mu, glued)
    assert closed.tolist() == [False, True, True, True]
    assert sliding.tolist() == [False, False, True, False]
    np.testing.assert_allclose(f, [[0, 0, 0], [1e6, -2e5, 0], [1e6, -5e5, 0],
                                   [-1e5, -3e5, 0]], atol=1e-6)
    np.testing.assert_allclose(after, [[3e-4, 0], [0, 0], [1.5e-3, 0], [0, 0]], atol=1e-15)
    # the slider: dN/dg_n = -k_n, dT/dg_n = -mu k_n e_t = +5e8, dS/dg_s = -k_t mu N / |F*|
    np.testing.assert_allclose(D[2], [[-1e9, 0, 0], [5e8, 0, 0], [0, 0, -2.5e8]])
    rng = np.random.default_rng(3)
    g = np.array([[-1e-3, 2e-4, 1e-4], [-1e-3, 1.5e-3, -1e-3], [2e-4, 1e-4, -3e-4]])
    slip = rng.normal(scale=1e-4, size=(3, 2))
    args = (slip, kn[:3], kt[:3], mu[:3], np.array([False, False, True]))
    D = path.joint_forces(g, *args)[1]
    h = 1e-9
    for k in range(3):
        step = np.zeros_like(g)
        step[:, k] = h
        diff = (path.joint_forces(g + step, *args)[0] - path.joint_forces(g - step, *args)[0])
        np.testing.assert_allclose(D[:, :, k], diff / (2 * h), rtol=1e-6, atol=1e-6 * 1e9)


def test_the_load_path_matrix_and_forces_are_those_of_the_equilibrium_matrix():
    """The kernels' ``B^T u``, ``B f`` and ``B D B^T`` on the free dofs against the
    equilibrium matrix of the statics (assembled independently, by scipy) on the arch, for
    random displacements, forces and point tangents."""
    m = rigid_model(build_scene(load_case(ARCH)))
    points = path._Points(m, linear="lu")
    free = np.flatnonzero(m.free)
    B = statics.equilibrium_matrix(m).toarray()[free]
    rng = np.random.default_rng(5)
    x = rng.normal(size=len(free))
    f = rng.normal(size=(m.points, 3))
    D = rng.normal(size=(m.points, 3, 3))
    np.testing.assert_allclose(points.gap(x).ravel(), B.T @ x, atol=1e-12)
    np.testing.assert_allclose(points.force(f), B @ f.ravel(), atol=1e-12)
    blocks = np.zeros((3 * m.points, 3 * m.points))
    for a in range(m.points):
        blocks[3 * a:3 * a + 3, 3 * a:3 * a + 3] = D[a]
    J = sp.csc_matrix((points.matrix(D, c=2.0), points.indices, points.indptr),
                      shape=(len(free), len(free))).toarray()
    np.testing.assert_allclose(J, B @ blocks @ B.T - 2.0 * np.eye(len(free)), atol=1e-10)


@pytest.mark.parametrize("width, height, mu", [(0.1, 0.4, 0.6), (0.3, 0.4, 0.5)])
def test_the_load_path_topples_or_slides_the_block(width, height, mu):
    """The tilting table followed from rest on the base's springs: the block topples about its
    toe at b/h when b/h < mu and slides at mu otherwise, within the bracket's width (``RTOL``
    of the multiplier) below the exact value."""
    m = rigid_model(tilting_block(width=width, height=height, mu=mu))
    sol, record = follow_load(m)
    expected = min(width / height, mu)
    lo, hi = record["bracket"]
    assert expected * (1.0 - 2.0 * path.RTOL) <= lo <= expected * (1.0 + 1e-9) <= hi
    assert sol.multiplier == lo
    kinds = [j["kind"] for j in mechanism.joints(m, sol.point_velocity, {"groups": ["base"]})]
    assert kinds == (["hinge"] if width / height < mu else ["sliding"])


def test_the_load_path_slides_the_wedged_block_at_mu():
    """The block touching two walls without pressure (above): loaded from rest nothing presses
    the walls, which carry nothing, and the block slides on its base at lambda = mu."""
    mu = 0.5
    m = rigid_model(tilting_block(width=0.2, height=0.1, depth=0.2, mu=mu, walls=True,
                                  direction=(0.0, 0.0, 1.0)))
    sol, record = follow_load(m)
    lo, hi = record["bracket"]
    assert mu * (1.0 - 2.0 * path.RTOL) <= lo <= mu * (1.0 + 1e-9) <= hi
    side = m.group == 1  # nothing on the walls, to the equilibrium's tolerance
    assert np.abs(sol.forces[side]).max() < path.TOLERANCE * np.abs(sol.forces).max()


def test_the_load_path_tells_its_progress_by_the_clock(monkeypatch):
    """A load step of a large scene runs viscous steps of seconds each: the user is told how
    far the blocks have moved at most every ``REPORT_S`` seconds, not after a count of steps
    (with it at zero, before every viscous step; at its default, never on this small one)."""
    m = rigid_model(tilting_block(width=0.2, height=0.1, depth=0.2, mu=0.5,
                                  direction=(0.0, 0.0, 1.0)))
    quiet: list[str] = []
    follow_load(m, progress=quiet.append)
    assert not any("flowing after" in line for line in quiet)
    monkeypatch.setattr(path, "REPORT_S", 0.0)
    told: list[str] = []
    _, record = follow_load(m, progress=told.append)
    flowing = [line for line in told if "flowing after" in line]
    assert len(flowing) == record["viscous_steps"]
    assert all(" mm" in line for line in flowing)


def test_the_load_path_finds_the_arch_four_hinges():
    """The shipped arch followed from rest (no joint slides at its mu): the kinematic theorem's
    least four-hinge multiplier within the bracket, with the same four hinges, from the
    command with its record."""
    expected, hinges = four_hinge_multiplier(24, 1.0, 0.15)
    lines: list[str] = []
    result = analyse(load_case(ARCH), flow="non-associative", method="load-path",
                     progress=lines.append)
    lo, hi = result.record["load_path"]["bracket"]
    # a line per load step: each step at rest, then the halvings above the multiplier
    assert sum("at rest" in line for line in lines) == result.record["load_path"]["steps"]
    assert "the step halved" in lines[-1]
    assert expected * (1.0 - 2.0 * path.RTOL) <= lo <= expected * (1.0 + 1e-9) <= hi
    assert result.solution.multiplier == lo == result.record["multiplier"]["value"]
    assert result.record["load_path"]["collapsed"]
    assert "collapse displacement" in result.record["multiplier"]["kind"]
    assert sorted((h["joint"], h["side"]) for h in result.record["hinges"]) == sorted(hinges)
    with pytest.raises(ValueError, match="load-path"):
        analyse(load_case(ARCH), flow="non-associative", method="load-path", tension=True)


def test_the_load_path_collapses_the_barrel_vault_by_its_staggered_ring():
    """Two rings of the barrel vault (the second staggered), high friction, followed from
    rest: the faces between the rings carry nothing, so the vault falls as its staggered
    ring, at the kinematic theorem's least four-hinge multiplier of that ring's voussoirs
    (within the bracket), with that ring's four hinges; each linear solver (PARDISO where
    installed, SuperLU) finds it."""
    case = load_case(CASES / "vault_barrel.yaml",
                     ["joint.mu=2.0", "vault.rings=2", "vault.depth_m=0.5"])
    expected = four_hinge_multiplier(0, 1.0, 0.15,
                                     geometry=ring_voussoirs(24, 1.0, 0.15, True))[0]
    result = analyse(case, flow="non-associative", method="load-path")
    record = result.record["load_path"]
    _, superlu = follow_load(result.model, linear="lu")
    for rec in (record, superlu):
        lo, hi = rec["bracket"]
        assert expected * (1.0 - 2.0 * path.RTOL) <= lo <= expected * (1.0 + 1e-9) <= hi
        assert rec["collapsed"]
    # the collapsing flow from the last state at rest: the mechanism, and the elastic part of
    # the last load increment (below 1e-4 of the fastest node)
    hinges = [h for h in result.record["hinges"] if h["max_opening_rate"] > 1e-3]
    assert len(hinges) == 4
    assert all(any(b.startswith("ring 2") for b in h["bodies"]) for h in hinges)


def test_the_command_refuses_the_load_path_with_tension(tmp_path):
    """``--method load-path`` with ``--tension`` (its springs carry none) or an unknown method:
    exit 2 with one message naming the option, nothing written."""
    runner = CliRunner()
    for extra, word in ((["--method", "load-path", "--tension"], "--tension"),
                        (["--method", "fastest"], "--method")):
        res = runner.invoke(app, ["limit", str(ARCH), "--flow", "non-associative", *extra,
                                  "-o", str(tmp_path / "out")])
        assert res.exit_code == 2
        assert res.output.count("error") == 1 and word in res.output
        assert not (tmp_path / "out").exists()
