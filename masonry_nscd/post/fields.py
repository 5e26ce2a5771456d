r"""Fields of one step, from the integrator's state: what the recorders write (SI units).

The output mesh is the structure of the scene (its units, not the supports): every body's
elements drawn as hexahedra (a tetrahedron as a collapsed one: ``Element.drawn_as``; a 10-node
one by its corners, its edge nodes among the nodes), nodes numbered body after body, ``block_of_element`` the position of the element's
body in ``scene.structure``. Per step:

* nodal displacements (m): the dofs of a block; ``q_0 + theta x (x - x_ref)`` on a rigid body
  (small rotations about its reference point);
* per element: the mean stress over its Gauss points (Pa, Voigt ``[xx, yy, zz, yz, xz, xy]``):
  ``C0 eps`` for linear elastic blocks, the apparent (damaged) stress for ENDO3D blocks, zero on
  rigid bodies; its von Mises equivalent ``sqrt(3 J2)``; the ENDO3D damages ``d_c``, ``d_cpp``,
  the largest ``d_t`` and crack opening (m), zero elsewhere;
* per contact point: the joint damage ``d_coh = 1 - beta (1 - d_0)`` with ``d_0`` the damage of
  the point's law as built (:func:`masonry_nscd.contact.laws.initial_damage`), the opening and
  slip (m), the normal and shear tractions (Pa), the status code and the group id, and the
  scene's per-point data (the drawn joint properties of ``joint.scatter``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from masonry_nscd.contact import laws
from masonry_nscd.fe import element as solid
from masonry_nscd.fe.catalog import element_of
from masonry_nscd.model import Block, RigidBody
from masonry_nscd.post.limit import classify_joints, state_codes


@dataclass
class OutputMesh:
    """The elements of the scene's structure drawn as hexahedra (reference coordinates, m)."""

    bodies: list[int]  # scene body index of each structure body
    nodes: np.ndarray  # (nn, 3)
    hexes: np.ndarray  # (ne, 8)
    block_of_element: np.ndarray  # (ne,) position in ``bodies``
    node_offsets: np.ndarray  # (nb + 1,)
    element_offsets: np.ndarray  # (nb + 1,)

    @classmethod
    def of(cls, scene) -> OutputMesh:
        geoms = [scene.bodies[i] for i in scene.structure]
        n_off = np.cumsum([0] + [len(g.X) for g in geoms])
        e_off = np.cumsum([0] + [len(g.conn) for g in geoms])
        nodes = np.concatenate([g.X for g in geoms]) if geoms else np.zeros((0, 3))
        hexes = np.concatenate([_drawn(g.conn) + n_off[k] for k, g in enumerate(geoms)]) \
            if geoms else np.zeros((0, 8), dtype=np.int64)
        owner = np.repeat(np.arange(len(geoms)), np.diff(e_off))
        return cls(list(scene.structure), nodes, hexes, owner, n_off, e_off)


def _drawn(conn: np.ndarray) -> np.ndarray:
    """Cells (ne, 8) of the hexahedra that draw the elements ``conn`` (module docstring)."""
    if not len(conn) or conn.shape[1] == 8:
        return conn.reshape(-1, 8)
    return conn[:, element_of(conn).drawn_as]


def point_initial_damage(params: np.ndarray, kind: np.ndarray, law: np.ndarray) -> np.ndarray:
    """Damage of each contact point's law as built (0 for glued points)."""
    d0 = np.array([laws.initial_damage(P) for P in params])
    return np.where(kind == laws.KIND_JOINT, d0[law], 0.0)


def von_mises(sig: np.ndarray) -> np.ndarray:
    """Von Mises stress (Pa) of Voigt stresses (n, 6)."""
    sxx, syy, szz, syz, sxz, sxy = sig.T
    return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2)
                   + 3.0 * (syz ** 2 + sxz ** 2 + sxy ** 2))


class StepFields:
    """Reads the fields of the current state of an integrator of a scene (module docstring)."""

    def __init__(self, scene, mesh: OutputMesh, integ):
        self.mesh = mesh
        self.integ = integ
        self.point_fields = scene.point_fields
        s = integ.sys
        self.joint = s.kind == laws.KIND_JOINT
        self.d0 = point_initial_damage(integ.params, s.kind, s.law)
        self.group = np.array([p.group for p in integ.points], dtype=np.int64)
        # a limit-state scene marks the state of each point's joint (post/limit.py)
        rule = scene.collapse
        self._states = None if rule is None or not integ.points else (
            np.array([p.x for p in integ.points]), np.array([p.frame[0] for p in integ.points]),
            np.array([p.bodies for p in integ.points], dtype=np.int64),
            [scene.groups.index(g) for g in scene.joint_groups], rule.hinge_opening_m)
        mat = integ.material
        # output elements of the ENDO3D blocks, in the order of ``mat.index``
        pos = {b: k for k, b in enumerate(mesh.bodies)}
        self._endo = np.concatenate(
            [np.arange(mesh.element_offsets[pos[i]], mesh.element_offsets[pos[i] + 1])
             for i in mat.index]) if mat is not None else np.zeros(0, dtype=np.int64)
        self._stress_maps: dict[int, np.ndarray] = {}

    def _stress_map(self, i: int) -> np.ndarray:
        """The map from the nodal displacements of elastic block ``i`` to its elements' mean
        stresses (``fe.element.mean_stress_map``), built once."""
        if i not in self._stress_maps:
            body = self.integ.bodies[i]
            self._stress_maps[i] = solid.mean_stress_map(
                body.X, body.conn, solid.elastic_matrix(body.E, body.nu), body.element)
        return self._stress_maps[i]

    def joint_damage(self) -> np.ndarray:
        """``d_coh = 1 - beta (1 - d_0)`` per contact point."""
        return 1.0 - self.integ.joints.beta * (1.0 - self.d0)

    def block_damage(self) -> dict[str, np.ndarray]:
        """Per element: ENDO3D ``d_c``, ``d_cpp``, ``d_t``, ``crack_opening_m`` (zero elsewhere)."""
        nel = len(self.mesh.hexes)
        out = {k: np.zeros(nel) for k in ("d_c", "d_cpp", "d_t", "crack_opening_m")}
        mat = self.integ.material
        if mat is not None:
            f = mat.element_fields()
            for k, arr in out.items():
                arr[self._endo] = f[k]
        return out

    def element_stress(self) -> np.ndarray:
        """Mean stress of each element (ne, 6), Pa (module docstring)."""
        integ, mesh = self.integ, self.mesh
        out = np.zeros((len(mesh.hexes), 6))
        mat = integ.material
        if mat is not None:
            out[self._endo] = mat.element_fields()["stress_Pa"]
        endo = set(mat.index) if mat is not None else set()
        for k, i in enumerate(mesh.bodies):
            body = integ.bodies[i]
            if not isinstance(body, Block) or i in endo:
                continue
            out[mesh.element_offsets[k]:mesh.element_offsets[k + 1]] = \
                (self._stress_map(i) @ integ.u[integ.body_dofs(i)]).reshape(-1, 6)
        return out

    def nodal_displacement(self) -> np.ndarray:
        """Displacement of every output node (nn, 3), m."""
        integ, mesh = self.integ, self.mesh
        d = np.zeros_like(mesh.nodes)
        for k, i in enumerate(mesh.bodies):
            body = integ.bodies[i]
            rows = slice(mesh.node_offsets[k], mesh.node_offsets[k + 1])
            q = integ.u[integ.body_dofs(i)]
            d[rows] = body.displacement_of(q, body.X) if isinstance(body, RigidBody) \
                else q.reshape(-1, 3)
        return d

    def joint_fields(self) -> dict[str, np.ndarray]:
        """Per contact point: damage, opening and slip (m), tractions (Pa), status, group;
        in a limit-state scene the state of its joint (``joint_state``: closed, partly open,
        open, sliding, hinge, :data:`masonry_nscd.post.limit.STATE_CODES`)."""
        j = self.integ.joints
        out = {"d_coh": self.joint_damage(), "opening_m": j.u[:, 0],
               "slip_m": np.hypot(j.u[:, 1], j.u[:, 2]), "T_n_Pa": j.T[:, 0],
               "T_t_Pa": np.hypot(j.T[:, 1], j.T[:, 2]), "status": j.status.astype(float),
               "group": self.group.astype(float), **self.point_fields}
        if self._states is not None:
            x, normal, bodies, ids, opening = self._states
            joints = classify_joints(x, normal, bodies, self.group, ids, j.u, opening)
            out["joint_state"] = state_codes(joints, len(x))
        return out

    def largest(self, damage: dict[str, np.ndarray]) -> tuple[float, float, float]:
        """The curve's damage columns: largest joint ``d_coh`` (joint points only), largest
        ``max(d_c, d_t)`` and largest ``d_cpp`` of the elements."""
        dj = float(self.joint_damage()[self.joint].max()) if self.joint.any() else 0.0
        if not len(self.mesh.hexes):
            return dj, 0.0, 0.0
        return (dj, float(np.maximum(damage["d_c"], damage["d_t"]).max()),
                float(damage["d_cpp"].max()))
