"""The wall on its test rig: a builder of the block assembly (model.md section 1).

Coordinates: x along the wall from its left end, y up from the bottom of its first course, z
through the thickness. The units come from the course layout (:mod:`masonry_nscd.scenes.layout`:
running, stack or pattern bond, openings, lintels), each a block meshed with
``elements_per_unit`` hexahedra (a lintel with as many per metre as a whole unit; the units of
``wall.refine`` as it says), or a rigid body with that mesh as its geometry.

The rig: two rigid steel beams 0.2 m tall, as long as the wall. The lower one is fixed. The
upper one has the mass ``supports.top_beam_mass_kg`` (centre 0.1 m above the wall), an in-plane
rotational inertia of a 0.2 m tall beam as long as the wall; its x velocity follows the
history of the horizontal stage (monotonic, cyclic or tabulated,
:mod:`masonry_nscd.loading.histories`) at its reference point, ``supports.load_height_m`` above
the wall (``U_x`` is that point's displacement), its z and out-of-plane rotations are held, its in-plane
rotation is held or free (``supports.top_rotation``), and in y it carries the vertical stress
times the wall's plan area (``load``), is held (``fixed``), or carries it and is then held from
the start of the horizontal stage (``load_then_fixed``). Gravity acts on the units only.

Joints are found by contact detection (:mod:`masonry_nscd.model.detection`) with the joint
thickness as the largest gap, and named: ``bed`` (horizontal) and ``head`` (vertical) joints
between units; between the wall and the beams ``glue_bottom`` and ``glue_top`` (bilateral
glue, the study's epoxy) or, with ``supports.beam_joints: joint_law``, joints of the joint
law ``bed_bottom`` and ``bed_top``. With ``supports.clamped_courses`` = k the k outer courses
at each end are part of their beam (and meet the wall on joints of the joint law unless the
case says glue). The points of the joints that ``joint.regions`` name take
their region's parameter row, and with ``joint.scatter`` the joint points take scattered rows
(:mod:`masonry_nscd.contact.scatter`). A bed joint lies on top of the lower of its two courses
(``bed_bottom``: the top clamped course at the bottom, or the beam, which no course number
names; ``bed_top``: the highest free course),
a head joint within its course; a lintel counts as the course it stands on.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from masonry_nscd.case.structures.wall import vertical_force_N
from masonry_nscd.contact import laws
from masonry_nscd.contact.scatter import scatter_rows
from masonry_nscd.fe import hex8
from masonry_nscd.loading import Loads, Ramp, at_rest
from masonry_nscd.materials.point_driver import params_from_case
from masonry_nscd.model import MAT_ELASTIC, MAT_ENDO3D, Block, RigidBody, dof_offsets
from masonry_nscd.model.bodies import body_mass
from masonry_nscd.model.detection import find_joints, joint_points
from masonry_nscd.scenes import Builder
from masonry_nscd.scenes.layout import LayoutError, count_index, unit_boxes, unit_divisions
from masonry_nscd.scenes.scene import Hold, Scene, SolverSettings, Stage

if TYPE_CHECKING:  # types of the annotations only: both load on use
    from masonry_nscd.loading.ground_motion import GroundMotion
    from masonry_nscd.loading.histories import DisplacementHistory

X, Y, Z = 0, 1, 2
ROT_Z = 5
#: Joint groups of a wall, in the order of their ids.
GROUPS = ("bed", "head", "glue_bottom", "glue_top", "bed_bottom", "bed_top")
BEAM_HEIGHT_M = 0.2


def unit_name(course: int, first: int, last: int, position: int, count: int) -> str:
    """``course 1 (bottom), unit 6 of 6 (right end)`` (course and position 1-based)."""
    name = f"course {course}" + (" (bottom)" if course == first else
                                 " (top)" if course == last else "")
    end = " (left end)" if count > 1 and position == 1 else \
        " (right end)" if count > 1 and position == count else ""
    return f"{name}, unit {position} of {count}{end}"


def build_wall(case) -> Scene:
    """The scene of a wall case: units, beams, joints, loads, stages (module docstring)."""
    w = case.wall
    clamped = case.supports.clamped_courses
    first, last = clamped, w.courses - 1 - clamped  # the courses between the beams
    bodies, info, top_course = _units(case, first, last)
    n_units = len(bodies)
    rig = _rig(case, first, last)
    bodies += rig.beams
    i_low = n_units
    i_up = n_units + 1 if len(rig.beams) == 2 else None
    points, params, drawn = _joints(case, bodies, i_low, i_up,
                                    [place["course"] - 1 for place in info])
    dof0 = dof_offsets(bodies)
    loads, holds = _loads(case, bodies, n_units, dof0, i_up)
    length, height = w.wall_length_m, w.wall_height_m
    meta = {"joint_thickness_m": w.joint_thickness_m, "wall_length_m": length,
            "wall_height_m": height, "vertical_stress_Pa": case.loading.vertical_stress.value_Pa,
            "vertical_force_N": vertical_force_N(case),
            "contact_point_rule": case.contact_point_rule}
    push = _push_stage(case, rig, bodies, dof0, top_course, i_low, i_up)
    if push.measured_what is not None:
        meta["measured"] = push.measured_what
    solver = SolverSettings.from_case(case, _endo3d_params(case))
    reactions = {"top": i_up, "bottom": i_low} if i_up is not None else {"bottom": i_low}
    return Scene(
        name=case.name, builder="wall",
        label=f"sigma_N {case.loading.vertical_stress.value_Pa:.4g} Pa", bodies=bodies,
        points=points, groups=GROUPS,
        params=params, loads=loads, solver=solver,
        point_fields={f"joint_{k}": v for k, v in drawn.items()},
        structure=list(range(n_units)), body_info=info, driven=push.driven,
        reactions=reactions, stages=push.stages, push_stage=push.name, target_m=push.target_m,
        expected_end_s=push.end_s, time_limit_s=push.limit_s, holds=holds,
        history=push.history, turns_s=push.turns_s, measured=push.measured, meta=meta,
    )


def _units(case, first: int, last: int) -> tuple[list, list[dict], list[int]]:
    """The units of courses ``first`` to ``last`` (0-based): their bodies (blocks meshed as
    ``wall.elements_per_unit`` and ``wall.refine`` say, or rigid bodies), their places
    (``body_info``), and the indices of those of the course ``last``."""
    w, blk = case.wall, case.blocks
    every = unit_boxes(w)
    divisions = unit_divisions(w, every)
    boxes = [(b, d) for b, d in zip(every, divisions) if first <= b.course <= last]
    count = {c: sum(1 for b, _ in boxes if b.course == c) for c in range(first, last + 1)}
    bodies: list = []
    info = []
    for b, div in boxes:
        name = unit_name(b.course + 1, first + 1, last + 1, b.index + 1, count[b.course])
        place = {"name": name, "course": b.course + 1, "position_in_course": b.index + 1,
                 "units_in_course": count[b.course]}
        material = MAT_ENDO3D if blk.material == "endo3d" else MAT_ELASTIC
        if b.kind == "lintel":
            name = place["name"] = f"lintel over opening {b.opening + 1}"
            material = MAT_ELASTIC
        origin, size = (b.x0, b.y0, 0.0), (b.length, b.height, w.thickness_m)
        if blk.material == "rigid":
            bodies.append(RigidBody.box(origin, size, blk.density_kg_m3, div, name=name))
        else:
            bodies.append(Block.box(origin, size, div, E=blk.E_Pa, nu=blk.nu,
                                    density=blk.density_kg_m3, material=material, name=name))
        info.append(place)
    top_course = [i for i, (b, _) in enumerate(boxes) if b.course == last]
    return bodies, info, top_course


class _Rig(NamedTuple):
    """The beams of the rig: ``[lower, upper]`` or ``[lower]`` (``supports.top_beam``
    absent), and the motion that drives the run: the horizontal stage's history (None under
    a ground motion) or the ground motion's (None otherwise)."""

    beams: list
    history: DisplacementHistory | None
    ground: GroundMotion | None


def _rig(case, first: int, last: int) -> _Rig:
    """The two rigid steel beams (module docstring): the lower one fixed or moved by the
    ground motion, the upper one driven in x by the horizontal stage's history, with the
    supports' holds."""
    w, sup, ld = case.wall, case.supports, case.loading
    length, height = w.wall_length_m, w.wall_height_m
    t = w.thickness_m
    levels = w.course_levels()
    y_low = levels[first - 1][1] if first else 0.0  # top of the lower beam
    y_up = levels[last + 1][0] if last + 1 < w.courses else height  # bottom of the upper one
    Xl, cl = hex8.box_mesh(np.array([0.0, -BEAM_HEIGHT_M, 0.0]),
                           np.array([length, y_low + BEAM_HEIGHT_M, t]), (1, 1, 1))
    gm = ld.ground_motion
    ground = gm.history() if gm is not None else None
    if ground is None:
        lower = RigidBody.fixed(center=(length / 2, -BEAM_HEIGHT_M / 2, t / 2),
                                name="lower beam", X=Xl, conn=cl)
        history = ld.horizontal.displacement_history()
        imposed = {X: history.velocity, Z: at_rest, 3: at_rest, 4: at_rest, ROT_Z: at_rest}
    else:  # the base moves with the record; the top beam is free in x
        motion = dict.fromkeys(range(6), at_rest)
        motion[X if gm.direction == "x" else Y] = ground
        lower = RigidBody(center=(length / 2, -BEAM_HEIGHT_M / 2, t / 2), mass=1.0,
                          inertia=np.ones(3), imposed_velocity=motion, name="lower beam",
                          X=Xl, conn=cl, support=True)
        history = None
        imposed = {Z: at_rest, 3: at_rest, 4: at_rest, ROT_Z: at_rest}
    if sup.top_vertical == "fixed":
        imposed[Y] = at_rest
    if sup.top_rotation == "free":
        del imposed[ROT_Z]
    m_beam = sup.top_beam_mass_kg
    # in-plane rotational inertia of a beam as long as the wall and 0.2 m tall (kg m^2); the
    # other two rotations are held
    inertia = np.array([1.0, 1.0, m_beam * (length ** 2 + BEAM_HEIGHT_M ** 2) / 12.0])
    Xu, cu = hex8.box_mesh(np.array([0.0, y_up, 0.0]),
                           np.array([length, height + BEAM_HEIGHT_M - y_up, t]), (1, 1, 1))
    upper = RigidBody(center=(length / 2, height + BEAM_HEIGHT_M / 2, t / 2), mass=m_beam,
                      inertia=inertia, imposed_velocity=imposed, name="upper beam", X=Xu,
                      conn=cu, reference=(length / 2, height + sup.load_height_m, t / 2),
                      support=True)
    beams = [lower, upper] if sup.top_beam == "present" else [lower]
    return _Rig(beams, history, ground)


def _joints(case, bodies: list, i_low: int, i_up: int | None, course_of: list[int]):
    """The joint points between the bodies (contact detection up to the joint thickness),
    named by group (module docstring), with their rows of parameters, the regions' and
    scattered ones as ``joint.regions`` and ``joint.scatter`` say: ``(points, params,
    drawn)``. ``course_of``: the course of each unit (0-based)."""
    glued = case.supports.beam_joints == "glue"
    beam_group = {i_low: "glue_bottom" if glued else "bed_bottom"}
    if i_up is not None:
        beam_group[i_up] = "glue_top" if glued else "bed_top"

    def classify(joint, antagonist):
        pair = (joint.candidate.body, antagonist.body)
        beam = next((b for b in pair if b in beam_group), None)
        if beam is not None:
            name = beam_group[beam]
        else:
            name = "bed" if abs(joint.normal[Y]) > 0.5 else "head"
        kind = laws.KIND_GLUED if name.startswith("glue") else laws.KIND_JOINT
        return GROUPS.index(name), kind, 0

    w = case.wall
    detection = find_joints(bodies, max_gap=w.joint_thickness_m)
    points = joint_points(bodies, detection.joints, classify, n_gauss=w.contact_points_per_face,
                          rule=case.contact_point_rule)
    params, rows, drawn = scatter_rows(
        case.joint, points, np.array([p.kind == laws.KIND_JOINT for p in points], dtype=bool),
        _regions(case, points, course_of))
    for p, row in zip(points, rows):
        p.law = int(row)
    return points, params, drawn


def _regions(case, points: list, course_of: list[int]) -> np.ndarray | None:
    """The index in ``joint.regions`` of each point's region, the last that names its joint
    (-1: none; None without regions); ValueError for a region that names no joint (the case
    checks the courses; an opening can still take every joint of a course away)."""
    regions = case.joint.regions
    if not regions:
        return None
    n, k = case.wall.courses, case.supports.clamped_courses
    kind = {GROUPS.index(g): "bed" for g in ("bed", "bed_bottom", "bed_top")}
    kind[GROUPS.index("head")] = "head"
    lower = {GROUPS.index("bed_bottom"): k - 1, GROUPS.index("bed_top"): n - 1 - k}
    place = []  # (kind, course) of each point; kind None: glue
    for p in points:
        units = [course_of[b] for b in p.bodies if b < len(course_of)]
        place.append((kind.get(p.group), lower.get(p.group, min(units) if units else -1)))
    out = np.full(len(points), -1, dtype=np.int64)
    for r, region in enumerate(regions):
        courses = None if region.courses is None else {
            count_index(c, n, "courses", f"joint.regions[{r}].courses") for c in region.courses}
        hit = [a for a, (what, c) in enumerate(place)
               if what == region.joints and (courses is None or c in courses)]
        if not hit:
            raise ValueError(f"joint.regions[{r}]: no {region.joints} joint of the joint law "
                             "in those courses (an opening or the clamped courses take them)")
        out[hit] = r
    return out


def _loads(case, bodies: list, n_units: int, dof0: np.ndarray,
           i_up: int | None) -> tuple[Loads, list[Hold]]:
    """Gravity on the units and the vertical stress on the upper beam, each with its tanh
    ramp, and the hold of the upper beam in y once the horizontal stage starts
    (``load_then_fixed``)."""
    sup, ld = case.supports, case.loading
    loads = Loads()
    G = np.zeros(int(dof0[-1]))
    for i, b in enumerate(bodies[:n_units]):
        if isinstance(b, RigidBody):
            G[dof0[i]:dof0[i + 1]] = b.weight_load((0.0, -1.0, 0.0))
        else:
            G[dof0[i] + Y:dof0[i + 1]:3] = -b.lumped_mass()[Y::3]
    g = ld.gravity
    loads.add(G, Ramp(g.value_m_s2, g.start_s, g.ramp_s))
    holds = []
    if i_up is not None and sup.top_vertical in ("load", "load_then_fixed"):
        length = case.wall.wall_length_m
        vs = ld.vertical_stress
        Fv = np.zeros(int(dof0[-1]))
        Fv[dof0[i_up] + Y] = -vs.value_Pa * length * case.wall.thickness_m
        loads.add(Fv, Ramp(1.0, vs.start_s, vs.ramp_s))
    if sup.top_vertical == "load_then_fixed":
        holds.append(Hold(i_up, Y, ld.horizontal.start_s))
    return loads, holds


def _endo3d_params(case):
    """The ENDO3D parameters of the blocks (None unless ``blocks.material`` is endo3d)."""
    if case.blocks.material != "endo3d":
        return None
    return params_from_case(case)


class _Push(NamedTuple):
    """The stage that drives the run and how it ends and is measured (``Scene``'s fields of
    the same meaning)."""

    stages: list[Stage]
    name: str
    driven: int
    target_m: float | None
    end_s: float
    limit_s: float
    history: dict
    measured: tuple | None
    measured_what: str | None  # the scene's ``meta["measured"]`` (None: the driven beam)
    turns_s: tuple = ()  # the scene's ``turns_s``


def _push_stage(case, rig: _Rig, bodies: list, dof0: np.ndarray, top_course: list[int],
                i_low: int, i_up: int | None) -> _Push:
    """The stages (gravity, the vertical stress, then the horizontal stage or the ground
    motion), when the run stops, what drives it and what the curve measures; under a ground
    motion the drift is measured relative to the base, at the top beam's reference point or
    at the top course's centre of mass."""
    ld = case.loading
    stages = [Stage("gravity", 0.0), Stage("vertical", ld.vertical_stress.start_s)]
    ground = rig.ground
    if ground is None:
        hz, history = ld.horizontal, rig.history
        if history.end_s is None:  # monotonic: stop on the displacement (time as a guard)
            target, end, limit = hz.target_m, ld.end_time_s, ld.end_time_s + 0.5 * hz.ramp_s
        else:  # cyclic, table: stop when the motion is over
            target, end, limit = None, history.end_s, history.end_s
        stages.append(Stage("horizontal", hz.start_s))
        return _Push(stages, "horizontal", i_up, target, end, limit, history.info(), None,
                     None, history.turns_s())
    # run to the end of the record; drift relative to the base
    gm = ld.ground_motion
    stages.append(Stage("ground_motion", gm.start_s))
    info_history = {"kind": "ground_motion", "end_s": ground.end_s, "cycles": [],
                    "record": gm.file, "scale": gm.scale, "direction": gm.direction,
                    "start_s": gm.start_s,
                    "peak_acceleration_m_s2": ground.peak_acceleration_m_s2}
    if i_up is not None:
        points_x = [(int(dof0[i_up] + X), 1.0)]
        points_y = [(int(dof0[i_up] + Y), 1.0)]
        what = ("the top beam's reference point (supports.load_height_m above the wall) "
                "relative to the base")
    else:
        points_x, points_y = _centre_of_mass_dofs(bodies, dof0, top_course)
        what = "the centre of mass of the top course relative to the base"
    measured = (_relative(points_x, int(dof0[i_low] + X)),
                _relative(points_y, int(dof0[i_low] + Y)))
    return _Push(stages, "ground_motion", i_low, None, ground.end_s, ground.end_s,
                 info_history, measured, what)


def _relative(points: list[tuple[int, float]], base: int) -> tuple[np.ndarray, np.ndarray]:
    """Dofs and weights of a weighted displacement minus the base's (``base`` dof)."""
    dofs = np.array([d for d, _ in points] + [base], dtype=np.int64)
    weights = np.array([wt for _, wt in points] + [-1.0])
    return dofs, weights


def _centre_of_mass_dofs(bodies: list, dof0: np.ndarray, which: list[int]):
    """``(dof, weight)`` pairs whose sums are the x and the y displacement of the centre of
    mass of the bodies ``which`` (small rotations of rigid bodies about their reference
    point: ``u_c = q + omega x (c - reference)``)."""
    xs, ys = [], []
    masses = [body_mass(bodies[i]) for i in which]
    total = sum(masses)
    for i, m in zip(which, masses):
        b, d0 = bodies[i], int(dof0[i])
        if isinstance(b, RigidBody):
            dx, dy, dz = b.center - b.reference
            f = m / total
            # (omega x d)_x = omega_y d_z - omega_z d_y; (omega x d)_y = omega_z d_x - omega_x d_z
            xs += [(d0 + X, f), (d0 + 4, f * dz), (d0 + ROT_Z, -f * dy)]
            ys += [(d0 + Y, f), (d0 + ROT_Z, f * dx), (d0 + 3, -f * dz)]
        else:
            lm = b.lumped_mass()
            xs += [(d0 + k, float(lm[k]) / total) for k in range(X, b.ndof, 3)]
            ys += [(d0 + k, float(lm[k]) / total) for k in range(Y, b.ndof, 3)]
    return xs, ys


def check(case) -> list[tuple[str, str]]:
    """The problems of a wall case that need its layout: a layout that cannot be built
    (``scenes/layout.py``: a pattern's courses, openings, refined units), an opening that
    reaches into a clamped course, and ``joint.regions`` naming courses without joints of the
    joint law."""
    w = case.wall
    try:
        unit_divisions(w, unit_boxes(w))
    except LayoutError as exc:
        return [(f"wall.{exc.field}", exc.message)]
    problems = []
    clamped = case.supports.clamped_courses
    if clamped and 2 * clamped < w.courses:
        levels = w.course_levels()
        free = (levels[clamped - 1][1], levels[-clamped][0])
        for i, op in enumerate(w.openings):
            if op.y_m < free[0] - 1e-9 or op.y_m + op.height_m > free[1] + 1e-9:
                problems.append((f"wall.openings[{i}]", (
                    f"reaches into a clamped course (the wall between the beams spans y = "
                    f"{free[0]:.6g} to {free[1]:.6g} m)")))
    return problems + _region_problems(case)


def _region_problems(case) -> list[tuple[str, str]]:
    """The courses of ``joint.regions`` against the wall's: each must have joints of the joint
    law of that kind (a bed joint on top of it, head joints in it) between the beams, not the
    glue and not inside a clamped course."""
    sup = case.supports
    n, k = case.wall.courses, sup.clamped_courses
    if sup.beam_joints == "joint_law":  # the joint under the lowest course names no course
        bed = (max(k - 1, 0), n - 1 - k if sup.top_beam == "present" else n - 2)
    else:
        bed = (k, n - 2 - k)
    spans = {"bed": bed, "head": (k, n - 1 - k)}
    problems = []
    for i, region in enumerate(case.joint.regions):
        lo, hi = spans[region.joints]
        field = f"joint.regions[{i}].courses"
        for c in region.courses or []:
            try:
                course = count_index(c, n, "courses", field)
            except LayoutError as exc:
                problems.append((exc.field, exc.message))
                continue
            if not lo <= course <= hi:
                problems.append((field, (
                    f"got {c}; course {course + 1} has no {region.joints} joint of the "
                    f"joint law (glued or clamped): allowed courses {lo + 1} to {hi + 1}")))
    return problems


def describe(case) -> str:
    """One line on a wall case (``masonry validate``)."""
    w, loading = case.wall, case.loading
    openings = f", {len(w.openings)} opening{'s' if len(w.openings) > 1 else ''}" \
        if w.openings else ""
    return (
        f"{case.name}: {len(unit_boxes(w))} units in {w.courses} courses "
        f"({w.bond} bond{openings}, {w.wall_length_m:.3f} x {w.wall_height_m:.3f} m), "
        f"blocks {case.blocks.material}, joints {case.joint.law}, "
        f"sigma_N = {loading.vertical_stress.value_Pa / 1e6:g} MPa "
        f"({vertical_force_N(case) / 1e3:g} kN), "
        f"{history_text(loading.horizontal, loading.ground_motion)}, "
        f"about {case.step_count} steps of {case.solver.time_step_s:g} s"
        + (f" (fewer: adaptive up to {case.solver.time_step_s * (1 << case.step_growth):g} s)"
           if case.step_growth else "")
    )


def history_text(hz, gm=None) -> str:
    """``U_x to 10 mm``, ``U_x cycles of +-1, 2 mm (2 per amplitude)``, ``U_x from FILE``,
    ``base motion x from FILE (x 1.5)``."""
    if gm is not None:
        return f"base motion {gm.direction} from {gm.file} (x {gm.scale:g})"
    if hz.history == "cyclic":
        amps = ", ".join(f"{1e3 * a:g}" for a in hz.amplitudes_m)
        return f"U_x cycles of +-{amps} mm ({hz.cycles_per_amplitude} per amplitude)"
    if hz.history == "table":
        return f"U_x from {hz.file}"
    return f"U_x to {hz.target_m * 1e3:g} mm"


BUILDER = Builder("wall", build_wall, describe, check)
