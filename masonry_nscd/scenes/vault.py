r"""The barrel vault: an arch extruded along its depth in rings of voussoirs.

Coordinates and the arch's cross-section as in :mod:`masonry_nscd.scenes.arch`: x horizontal
from the middle of the span, y up from the springing line, z along the vault's axis,
``0 <= z <= D`` (``D = vault.depth_m``). SI units.

Rings. The depth is cut into ``r`` rings (``vault.rings``), ring ``i`` (from 1) over
``(i - 1) D / r <= z <= i D / r``; the rings touch along the planes ``z = i D / r`` (joint
group ``ring``). Every ring has the cross-section of the arch of ``n`` voussoirs
(``vault.voussoirs``), cut along the radial joint lines of the arch of ``2 n`` voussoirs
(:func:`~masonry_nscd.scenes.arch.arch_geometry` with ``2 n``: its joints ``0, 2, 4, ... 2 n``
are the ``n``-voussoir arch's): the half voussoirs ``h = 0 .. 2 n - 1``.

* An odd ring (1, 3, ...), or every ring without ``vault.stagger``: voussoir ``k`` is the half
  voussoirs ``2k - 2`` and ``2k - 1``, its joints those of the arch of ``n`` voussoirs.
* An even ring with ``stagger``: a half voussoir at each springing (half 0, half ``2n - 1``) and
  ``n - 1`` whole voussoirs between (halves ``2k - 1`` and ``2k``): its radial joints fall in
  the middle of its neighbours' voussoirs (running bond along the ring), ``n + 1`` voussoirs.

Every block is thus made of pieces of one common polygon (the ``2 n``-gon of the half
voussoirs' chords), so the faces of two rings meet on the planes ``z = const`` corner to corner
and the generic contact detection puts a point at every corner of every piece (with Gauss-
Lobatto points; a corner on the joint line of two blocks of the neighbour ring is made for
each). The cross-section of a ring differs from the arch of ``n`` chord-bounded voussoirs by
the middle vertex of each voussoir on the circle: the section's area is
``(R_e^2 - R_i^2) n sin(pi / (2 n))`` against ``(R_e^2 - R_i^2) n sin(pi / n) / 2``
(0.2 % more for ``n = 24``).

Blocks are named ``ring i voussoir k``; the abutments, the joints' law, the loads and the
collapse rule are the arch's (:func:`~masonry_nscd.scenes.arch.voussoir_scene`), the abutments
running along the whole depth. The curve's ``U_x``, ``U_y`` are the displacements of the crown
voussoir of ring 1.
"""

from __future__ import annotations

from masonry_nscd.scenes import Builder
from masonry_nscd.scenes.arch import Voussoir, arch_geometry, voussoir_scene
from masonry_nscd.scenes.limit_loads import until_collapse
from masonry_nscd.scenes.scene import Scene


def _ring_halves(n: int, staggered: bool) -> list[tuple[int, int]]:
    """The half voussoirs ``[first, last]`` of each voussoir of a ring (module docstring)."""
    if not staggered:
        return [(2 * k, 2 * k + 1) for k in range(n)]
    return [(0, 0), *[(2 * k - 1, 2 * k) for k in range(1, n)], (2 * n - 1, 2 * n - 1)]


def vault_voussoirs(v) -> tuple[list[Voussoir], int]:
    """The voussoirs of a vault section ``v``, ring by ring, and the index of ring 1's crown
    voussoir."""
    n = v.voussoirs
    half = arch_geometry(v.shape, v.centreline_radius_m, v.centreline_span_m, v.thickness_m,
                         2 * n)
    crown = arch_geometry(v.shape, v.centreline_radius_m, v.centreline_span_m, v.thickness_m,
                          n).keystone
    depth = v.depth_m / v.rings
    out: list[Voussoir] = []
    for i in range(1, v.rings + 1):
        pieces = _ring_halves(n, v.staggered(i))
        for k, (lo, hi) in enumerate(pieces):
            role = "left springer" if k == 0 else "right springer" if k == len(pieces) - 1 \
                else ""
            out.append(Voussoir(f"ring {i} voussoir {k + 1}", role, half.quads[lo:hi + 1],
                                ((i - 1) * depth, i * depth), {"ring": i, "voussoir": k + 1}))
    return out, crown


def describe(case) -> str:
    """One line on a vault case (``masonry validate``)."""
    v = case.vault
    blocks = len(v.voussoir_names())
    return (f"{case.name}: {v.shape} barrel vault of {v.rings} rings x {v.voussoirs} voussoirs"
            f"{' (staggered)' if v.stagger and v.rings > 1 else ''}, {blocks} blocks, radius "
            f"{v.centreline_radius_m:.4g} m, span {v.centreline_span_m:.4g} m, thickness "
            f"{v.thickness_m:.4g} m, depth {v.depth_m:.4g} m, {v.abutments} abutments, blocks "
            f"{case.blocks.material}, joints {case.joint.law}; {until_collapse(case)}")


def build_vault(case) -> Scene:
    """The scene of a vault case (module docstring)."""
    v = case.vault
    voussoirs, driven = vault_voussoirs(v)
    meta = {"shape": v.shape, "radius_m": v.centreline_radius_m,
            "span_m": v.centreline_span_m, "thickness_m": v.thickness_m,
            "depth_m": v.depth_m, "voussoirs": v.voussoirs, "rings": v.rings,
            "stagger": bool(v.stagger), "abutments": v.abutments, "blocks": len(voussoirs)}
    return voussoir_scene(case, v, voussoirs, driven, "vault", meta)


BUILDER = Builder("vault", build_vault, describe)
