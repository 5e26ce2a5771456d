r"""A block assembly read from a mesh file: the builder of an ``assembly:`` case.

The mesh (:func:`masonry_nscd.io.mesh_file.read_block_mesh`) is a set of 8-node hexahedra
and 4- or 10-node tetrahedra, each tagged with its block (Gmsh: its physical volume); the
elements of one tag are one block (of one element type), named by its physical name (or ``block <tag>``), its nodes renumbered from 0. Blocks
are in the order of their tags. y is up: gravity acts along -y. SI units.

* A block named in ``assembly.supports`` is a fixed support (a rigid body whose six dofs are
  held at rest); its joints with the structure follow the joint law (``kind: fixed``, group
  ``support``) or are glued (``kind: glued``, group ``glue``: no opening, no slip).
* Every other block is the structure's: rigid (:meth:`RigidBody.from_mesh`: mass, centre and
  inertia of its elements) or elastic, its material from ``assembly.materials`` (by name or
  tag) or from ``blocks``.
* Joints: the generic contact detection (:mod:`masonry_nscd.model.detection`) between facing
  planar faces at most ``assembly.joint_thickness_m`` apart (group ``joint`` between two blocks
  of the structure), points by ``contact_point_rule`` (``auto``: Gauss-Lobatto, the corners of
  the faces, where blocks hinge; ``overlap`` when a block is meshed with tetrahedra, whose
  triangular faces take no other rule).

Before anything is built the assembly is checked (:mod:`masonry_nscd.model.mesh_checks`):
inverted or flat elements, blocks that overlap (more than ``OVERLAP_TOL`` times the median
element size inside each other), and blocks that nothing holds (no joint to any other block,
or a group of blocks with no support); each problem names its blocks, and the case is refused
(exit 2).

Loads, collapse rule and outputs are those of a limit state
(:mod:`masonry_nscd.scenes.limit_loads`): gravity, the body force ``lambda g m``, a force on
one block at the middle of its top (the centre of its nodes in x and z, their highest y), and
the settlement of the support blocks that ``loading.settlement.blocks`` names (each moves by
``displacement_m`` along the tanh ramp, without rotating: the spreading of piers' footings;
``settlement_m`` is the length of that displacement). The
curve's ``U_x``, ``U_y`` are the reference point of ``assembly.driven_block`` (the highest block
by default); ``F_x``, ``F_y`` the force of all the supports on the structure, ``*_bottom`` that
of the first support of the list.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from masonry_nscd.contact import laws
from masonry_nscd.io.mesh_file import MeshFileError, read_block_mesh
from masonry_nscd.loading import at_rest
from masonry_nscd.model import MAT_ELASTIC, MAT_ENDO3D, Block, RigidBody, overlap
from masonry_nscd.model.detection import JOINT_ANGLE_TOL, find_joints, joint_points
from masonry_nscd.model.faces import gauss_points, locate
from masonry_nscd.model.mesh_checks import inverted_elements, overlapping_pairs, unheld_blocks
from masonry_nscd.scenes import Builder
from masonry_nscd.scenes.limit_loads import (
    limit_loads,
    limit_settings,
    support_motion,
    until_collapse,
)
from masonry_nscd.scenes.scene import Scene

#: Joint groups of an assembly, in the order of their ids.
GROUPS = ("joint", "support", "glue")
#: Blocks overlap when a point of one is more than this times the median element size inside
#: the other.
OVERLAP_TOL = 1e-6


class AssemblyError(ValueError):
    """An assembly that cannot be built: its problems, each ``(field, message)`` with the field
    relative to ``assembly`` and the message naming the blocks."""

    def __init__(self, field: str | list[tuple[str, str]], messages: list[str] | None = None):
        self.problems = [(field, m) for m in messages or []] if isinstance(field, str) \
            else list(field)
        super().__init__("; ".join(f"assembly.{f}: {m}" for f, m in self.problems))


@dataclass
class AssemblyBlocks:
    """The blocks of a checked mesh: per block its tag, name, nodes (m) and elements, its
    support kind (None: a block of the structure) and its material entry (None: ``blocks``)."""

    tags: list[int]
    names: list[str]
    meshes: list[tuple[np.ndarray, np.ndarray]]
    support: list[str | None]
    material: list = field(default_factory=list)
    joints: list = field(default_factory=list)  # the detected joints
    pairs: set = field(default_factory=set)  # the pairs of blocks joined by contact points

    def label(self, k: int) -> str:
        return f"block {self.names[k]!r} (tag {self.tags[k]})"


def _lookup(ref, tags: list[int], names: list[str]) -> int | None:
    if isinstance(ref, int) and ref in tags:
        return tags.index(ref)
    return names.index(str(ref)) if str(ref) in names else None


def _geometry_bodies(blocks: AssemblyBlocks) -> list[RigidBody]:
    """Bodies with the blocks' geometry only (for the contact detection)."""
    return [RigidBody(center=X.mean(axis=0), mass=1.0, inertia=np.ones(3), X=X, conn=c,
                      name=nm, support=s is not None,
                      imposed_velocity=dict.fromkeys(range(6), at_rest) if s else {})
            for (X, c), nm, s in zip(blocks.meshes, blocks.names, blocks.support, strict=True)]


def _faces_overlap(bodies, a, b) -> bool:
    """Whether an inner Gauss point of patch ``a``, projected along ``b``'s normal, falls in
    patch ``b`` (the two faces share some area, not only an edge); for triangular faces,
    whether a face of ``a`` clipped by one of ``b`` has an area."""
    if a.faces.shape[1] != 4 or b.faces.shape[1] != 4:
        basis = overlap.plane_basis(b.normal)
        Pa, Pb = bodies[a.body].X[a.corners] @ basis.T, bodies[b.body].X[b.corners] @ basis.T
        size = float(np.ptp(Pb.reshape(-1, 2), axis=0).max())
        return any(abs(overlap.signed_area(overlap.clip(p, q, 1e-9 * size)))
                   > 1e-12 * size * size for p in Pa for q in Pb)
    xs, _, _ = gauss_points(bodies[a.body].X[a.quads], 2, "gauss")
    xs = xs.reshape(-1, 3)
    xs = xs - np.outer(xs @ b.normal - b.offset, b.normal)
    return bool(locate(bodies[b.body].X[b.quads], xs)[2].any())


def _points_rule(a, blocks: AssemblyBlocks, rule: str) -> str:
    """The contact-point rule of the assembly's joints: ``rule`` (the case's, ``auto``
    resolved), or ``overlap`` when a block is meshed with tetrahedra (their triangular faces
    take no other) and the case left it to ``auto``; AssemblyError when it named another."""
    tets = [blocks.label(k) for k, (_, c) in enumerate(blocks.meshes) if c.shape[1] != 8]
    if not tets or rule == "overlap":
        return rule
    if a.contact_point_rule == "auto":
        return "overlap"
    verb = "is" if len(tets) == 1 else "are"
    raise AssemblyError("contact_point_rule", [
        (f"{', '.join(tets)} {verb} meshed with tetrahedra, whose triangular faces take the "
         f"rule overlap, not {rule!r}")])


#: The last assembly read: ``(key, blocks)``, the key the section and the mesh file's size and
#: time; a case is checked (``check``) and then built from the same file
_LAST_READ: tuple[tuple, AssemblyBlocks] | None = None


def read_assembly(a) -> AssemblyBlocks:
    """Read and check the mesh of the ``assembly`` section ``a`` (module docstring);
    AssemblyError naming the field and the blocks. The blocks of the last section read are
    kept, and given again while the section and its mesh file are unchanged."""
    global _LAST_READ
    try:
        st = os.stat(a.mesh_file)
        key = (a.model_dump_json(), st.st_mtime_ns, st.st_size)
    except (OSError, TypeError):
        key = None
    if key is not None and _LAST_READ is not None and _LAST_READ[0] == key:
        return _LAST_READ[1]
    blocks = _read_assembly(a)
    if key is not None:
        _LAST_READ = (key, blocks)
    return blocks


def _read_assembly(a) -> AssemblyBlocks:
    """:func:`read_assembly` without the cache."""
    try:
        mesh = read_block_mesh(a.mesh_file, a.tag_field)
    except MeshFileError as exc:
        raise AssemblyError("mesh_file", [str(exc)]) from None
    tags = [int(t) for t in mesh.block_tags()]
    names = [mesh.block_name(t) for t in tags]
    meshes = []
    for t in tags:
        try:
            cells = mesh.block_cells(t)
        except MeshFileError as exc:
            raise AssemblyError("mesh_file", [str(exc)]) from None
        used, local = np.unique(cells, return_inverse=True)
        meshes.append((mesh.points[used], local.reshape(cells.shape)))
    shown = ", ".join(f"{nm!r} ({t})" for nm, t in zip(names, tags, strict=True))
    problems = []
    support: list[str | None] = [None] * len(tags)
    material: list = [None] * len(tags)
    for table, target in (("supports", support), ("materials", material)):
        for i, entry in enumerate(getattr(a, table)):
            k = _lookup(entry.group, tags, names)
            if k is None:
                problems.append((f"{table}[{i}].group",
                                 (f"got {entry.group!r}; the mesh's blocks (name (tag)) are "
                                  f"{shown}")))
            elif table == "supports":
                target[k] = entry.kind
            else:
                target[k] = entry
    for k in range(len(tags)):
        if support[k] is not None and material[k] is not None:
            problems.append(("materials", (f"block {names[k]!r} is a support (fixed, rigid): "
                                           "it takes no material")))
    if problems:
        raise AssemblyError(problems)
    blocks = AssemblyBlocks(tags, names, meshes, support, material)
    bad = []
    for k, (X, c) in enumerate(meshes):
        inv = inverted_elements(X, c)
        if len(inv):
            kind = "hexahedra" if c.shape[1] == 8 else "tetrahedra"
            bad.append(f"{blocks.label(k)}: {len(inv)} of its {len(c)} {kind} inverted or "
                       f"flat (a corner Jacobian <= 0: nodes in the wrong order, or "
                       f"degenerate), the first ones {inv[:5].tolist()}")
    if bad:
        raise AssemblyError("mesh_file", bad)
    size = float(np.median([np.abs(np.ptp(X[c], axis=1)).max(axis=1).min()
                            for X, c in meshes]))
    over = overlapping_pairs(meshes, OVERLAP_TOL * size)
    if over:
        raise AssemblyError("mesh_file", [f"{blocks.label(i)} and {blocks.label(j)} overlap "
                                          "(a point of one inside the other)"
                                          for i, j in over])
    bodies = _geometry_bodies(blocks)
    detection = find_joints(bodies, max_gap=a.joint_thickness_m)
    joints = detection.joints
    skewed = sorted({(min(p.body, q.body), max(p.body, q.body)): angle
                     for p, q, angle in detection.skewed}.items())
    if skewed:
        raise AssemblyError("mesh_file", [
            f"{blocks.label(i)} and {blocks.label(k)} touch on faces {np.degrees(angle):.3g} "
            f"degrees from facing each other, beyond the joints' tolerance "
            f"({np.degrees(JOINT_ANGLE_TOL):.3g} degrees): no joint is made there (make the "
            "faces parallel)" for (i, k), angle in skewed])
    rule = _points_rule(a, blocks, a.contact_point_rule if a.contact_point_rule != "auto" else
                        ("lobatto" if a.contact_points_per_face >= 2 else "gauss"))
    points = joint_points(bodies, joints, lambda _j, _a: (0, laws.KIND_JOINT, 0),
                          n_gauss=a.contact_points_per_face, rule=rule)
    pairs = {tuple(sorted(p.bodies)) for p in points}
    missed = sorted({tuple(sorted((j.candidate.body, ant.body))) for j in joints
                     for ant in j.antagonists
                     if tuple(sorted((j.candidate.body, ant.body))) not in pairs
                     and _faces_overlap(bodies, ant, j.candidate)})
    if missed:
        raise AssemblyError("mesh_file", [
            f"{blocks.label(i)} and {blocks.label(k)} face each other, but no contact point of "
            "the face that carries them falls on the other (a face inside a larger one: give "
            "assembly.contact_point_rule: overlap, or split the larger face where the smaller "
            "ends, so that the faces meet corner to corner)"
            for i, k in missed])
    alone, floating = unheld_blocks(len(tags), pairs,
                                    [k for k, s in enumerate(support) if s is not None])
    msgs = [f"{blocks.label(k)} has no neighbour and no support (no face of it faces another "
            f"block's within joint_thickness_m = {a.joint_thickness_m:g} m)" for k in alone]
    if floating:
        msgs.append("blocks " + ", ".join(blocks.label(k) for k in floating)
                    + " hold together but no support holds them (name one in supports, or "
                      "join them to one)")
    if msgs:
        raise AssemblyError("mesh_file", msgs)
    blocks.joints, blocks.pairs = joints, pairs
    return blocks


def describe(case) -> str:
    """One line on an assembly case (``masonry validate``; reads and checks the mesh)."""
    a = case.assembly
    b = read_assembly(a)
    n_sup = sum(s is not None for s in b.support)
    return (f"{case.name}: assembly of {len(b.tags) - n_sup} blocks and {n_sup} supports from "
            f"{a.mesh_file} ({sum(len(c) for _, c in b.meshes)} elements, "
            f"{len(b.pairs)} joints), joints {case.joint.law}; {until_collapse(case)}")


def build_assembly(case) -> Scene:
    """The scene of an assembly case (module docstring)."""
    a, blk = case.assembly, case.blocks
    b = read_assembly(a)
    settle = case.loading.settlement
    moving = set(settle.blocks or ()) if settle is not None else set()  # the supports it moves
    bodies: list = []
    info = []
    for k, (X, c) in enumerate(b.meshes):
        name = b.names[k]
        if b.support[k] is not None:
            bodies.append(RigidBody(center=X.mean(axis=0), mass=1.0, inertia=np.ones(3),
                                    imposed_velocity=support_motion(settle, name in moving),
                                    name=name, X=X, conn=c, support=True))
            continue
        m = b.material[k]
        kind = m.material if m is not None else blk.material
        rho = m.density_kg_m3 if m is not None and m.density_kg_m3 is not None \
            else blk.density_kg_m3
        if kind == "rigid":
            bodies.append(RigidBody.from_mesh(X, c, rho, name=name))
        else:
            E = m.E_Pa if m is not None and m.E_Pa is not None else blk.E_Pa
            nu = m.nu if m is not None and m.nu is not None else blk.nu
            bodies.append(Block(X=X, conn=c, E=E, nu=nu, density=rho, name=name,
                                material=MAT_ENDO3D if kind == "endo3d" else MAT_ELASTIC))
        info.append({"name": name, "tag": b.tags[k], "material": kind})
    structure = [k for k, s in enumerate(b.support) if s is None]
    supports = [k for k, s in enumerate(b.support) if s is not None]
    names = [bd.name for bd in bodies]
    if a.driven_block is not None:  # a block of the structure (``check``)
        driven = names.index(a.driven_block)
    else:
        driven = max(structure, key=lambda k: bodies[k].X[:, 1].mean())

    def classify(joint, antagonist):
        pair = (joint.candidate.body, antagonist.body)
        held = [p for p in pair if b.support[p] is not None]
        if held and b.support[held[0]] == "glued":
            return GROUPS.index("glue"), laws.KIND_GLUED, 0
        return GROUPS.index("support" if held else "joint"), laws.KIND_JOINT, 0

    points = joint_points(bodies, b.joints, classify, n_gauss=a.contact_points_per_face,
                          rule=_points_rule(a, b, case.contact_point_rule))
    params = np.atleast_2d(laws.params_from_case(case.joint))

    def top_middle(k: int) -> np.ndarray:
        X = bodies[k].X
        return np.array([X[:, 0].mean(), X[:, 1].max(), X[:, 2].mean()])

    loads, stages, factors = limit_loads(case, bodies, structure, top_middle)
    stages.sort(key=lambda st: st.start_s)
    solver, rule = limit_settings(case, factors)
    col = case.collapse
    return Scene(
        name=case.name, builder="assembly", bodies=bodies, points=points, groups=GROUPS,
        params=params, loads=loads, solver=solver, structure=structure, body_info=info,
        driven=driven, reactions={"top": tuple(supports), "bottom": supports[0]},
        stages=stages, push_stage="gravity", target_m=None, expected_end_s=col.end_time_s,
        time_limit_s=col.end_time_s, history={"kind": "monotonic", "cycles": []},
        collapse=rule,
        meta={"contact_point_rule": _points_rule(a, b, case.contact_point_rule),
              "limit_state": True,
              "reaction_names": ["all supports", names[supports[0]]],
              "assembly": {"mesh_file": a.mesh_file, "blocks": len(structure),
                           "supports": {names[k]: b.support[k] for k in supports},
                           "supports_xy_m": [[*bodies[k].X[:, :2].min(axis=0).tolist(),
                                              *bodies[k].X[:, :2].max(axis=0).tolist()]
                                             for k in supports]}},
    )


def check(case) -> list[tuple[str, str]]:
    """The mesh file read and checked (``read_assembly``): its problems with
    their fields (``assembly.mesh_file``, ``assembly.supports[0].group``, ...), then the
    blocks that ``assembly.driven_block`` and the loads (``Loading.named_blocks``: the point
    load, the removal, the line loads) name, which must be blocks of the structure (not
    supports)."""
    try:
        b = read_assembly(case.assembly)
    except AssemblyError as exc:
        return [(f"assembly.{field}", text) for field, text in exc.problems]
    structure = [nm for nm, s in zip(b.names, b.support, strict=True) if s is None]
    listed = ", ".join(repr(nm) for nm in structure)
    named = (*case.loading.named_blocks(),
             ("assembly.driven_block", case.assembly.driven_block))
    problems = [(field, f"got {name!r}; the blocks of the structure are {listed}")
                for field, name in named if name is not None and name not in structure]
    settle = case.loading.settlement
    held = [nm for nm, s in zip(b.names, b.support, strict=True) if s is not None]
    for i, name in enumerate(getattr(settle, "blocks", None) or []):
        if name not in held:
            problems.append((f"loading.settlement.blocks[{i}]", (
                f"got {name!r}; a settlement moves support blocks, the assembly's are "
                + ", ".join(repr(nm) for nm in held))))
    return problems


BUILDER = Builder("assembly", build_assembly, describe, check)
