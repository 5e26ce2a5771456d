"""Write the mesh of cases/pier_arches.yaml: a pier between two half arches (Gmsh .msh).

    python cases/make_pier_arches_mesh.py              # writes cases/pier_arches.msh
    python cases/make_pier_arches_mesh.py --voussoirs 8 -o other.msh

The structure, in the x-y plane (y up), extruded along z over ``--depth`` (m):

* ``ground``: a slab under the pier, ``-0.5 <= x <= 0.5``, ``-0.2 <= y <= 0`` (a support; the
  case glues the pier to it);
* ``pier 1`` .. ``pier 5``: the pier, ``|x| <= 0.2``, five stacked blocks with their bed joints
  at ``y = 0.4, 0.8, 1.22, 1.38`` and its top at 1.6: ``pier 4`` spans the arches' crown
  joints exactly, so that the faces of each crown joint meet corner to corner (the contact
  points sit at the corners of one face of a joint and must fall on the other);
* ``right arch 1`` .. ``right arch n``: a quarter of a circular arch, centreline radius
  ``R = 0.8`` m and thickness ``t = 0.16`` m about the centre ``(0.2, 0.5)``: its crown joint is
  vertical, against the pier's right face (``x = 0.2``, ``1.22 <= y <= 1.38``), its springing
  joint horizontal at ``y = 0.5``; ``n`` voussoirs (``--voussoirs``) between radial joints
  equally spaced in angle, each a prism on the chords of its intrados and extrados, numbered
  from the pier; ``left arch k`` its mirror image;
* ``right abutment``, ``left abutment``: fixed blocks ``0.32`` m wide under the springings,
  ``-0.2 <= y <= 0.5`` (supports).

Each block is one physical volume of hexahedra (one hexahedron per voussoir and pier block, a
``2 x 1 x 2`` grid for the ground and the abutments, to show blocks of several elements), nodes
in the VTK / Gmsh order. The file is Gmsh's 2.2 format with physical names, written by meshio
through :func:`masonry_nscd.io.mesh_file.write_block_mesh` (Gmsh reads it; see
docs/choices.md for why not the Gmsh API).
"""

from __future__ import annotations

import argparse
import itertools
import math
from pathlib import Path

import numpy as np

from masonry_nscd.io.mesh_file import BlockMesh, write_block_mesh

PIER_HALF_WIDTH = 0.2  # m
RADIUS, THICKNESS, SPRINGING_Y = 0.8, 0.16, 0.5  # m
PIER_LEVELS = (0.0, 0.4, 0.8, SPRINGING_Y + RADIUS - THICKNESS / 2,
               SPRINGING_Y + RADIUS + THICKNESS / 2, 1.6)  # m, its bed joints
ABUTMENT_WIDTH, BASE_Y = 0.32, -0.2  # m


def hexes_of_prism(quad: np.ndarray, depth: float, nx: int = 1, nz: int = 1):
    """Nodes and hexahedra of the prism on the counter-clockwise quadrilateral ``quad`` (4, 2)
    extruded from z = 0 to ``depth``, ``nx`` elements along its edge 0-1 and ``nz`` along z
    (bilinear map), in VTK order."""
    s = np.linspace(0.0, 1.0, nx + 1)
    z = np.linspace(0.0, depth, nz + 1)
    nodes, index = [], {}
    for k, zk in enumerate(z):
        for j, r in enumerate((0.0, 1.0)):
            for i, si in enumerate(s):
                xy = ((1 - si) * (1 - r) * quad[0] + si * (1 - r) * quad[1]
                      + si * r * quad[2] + (1 - si) * r * quad[3])
                index[i, j, k] = len(nodes)
                nodes.append([xy[0], xy[1], zk])
    cells = [[index[i, 0, k], index[i + 1, 0, k], index[i + 1, 1, k], index[i, 1, k],
              index[i, 0, k + 1], index[i + 1, 0, k + 1], index[i + 1, 1, k + 1],
              index[i, 1, k + 1]] for k in range(nz) for i in range(nx)]
    return np.array(nodes), np.array(cells)


def _ccw(quad) -> np.ndarray:
    q = np.asarray(quad, dtype=float)
    area = 0.5 * sum(q[i, 0] * q[(i + 1) % 4, 1] - q[(i + 1) % 4, 0] * q[i, 1] for i in range(4))
    return q if area > 0 else q[[0, 3, 2, 1]]


def structure(voussoirs: int) -> list[tuple[str, np.ndarray, int]]:
    """The blocks as (name, counter-clockwise quadrilateral (4, 2), elements along edge 0-1)."""
    out = [("ground", _ccw([[-0.5, BASE_Y], [0.5, BASE_Y], [0.5, 0.0], [-0.5, 0.0]]), 2)]
    w = PIER_HALF_WIDTH
    for k, (y0, y1) in enumerate(itertools.pairwise(PIER_LEVELS)):
        out.append((f"pier {k + 1}", _ccw([[-w, y0], [w, y0], [w, y1], [-w, y1]]), 1))
    r_i, r_e = RADIUS - THICKNESS / 2, RADIUS + THICKNESS / 2
    theta = 0.5 * math.pi * (1.0 - np.arange(voussoirs + 1) / voussoirs)  # crown to springing
    for side, sign in (("right", 1.0), ("left", -1.0)):
        centre = np.array([sign * w, SPRINGING_Y])
        u = np.stack([sign * np.cos(theta), np.sin(theta)], axis=1)
        u[0] = (0.0, 1.0)  # exactly vertical crown joint, horizontal springing joint
        u[-1] = (sign, 0.0)
        for k in range(voussoirs):
            q = [centre + r_i * u[k], centre + r_i * u[k + 1], centre + r_e * u[k + 1],
                 centre + r_e * u[k]]
            out.append((f"{side} arch {k + 1}", _ccw(q), 1))
        xs = sign * (w + RADIUS)
        a = ABUTMENT_WIDTH / 2
        out.append((f"{side} abutment", _ccw([[xs - a, BASE_Y], [xs + a, BASE_Y],
                                              [xs + a, SPRINGING_Y], [xs - a, SPRINGING_Y]]), 2))
    return out


def pier_arches_mesh(voussoirs: int = 6, depth: float = 0.3) -> BlockMesh:
    """The block mesh of the module docstring (physical tags from 1 in the order above)."""
    points, hexes, tags, names = [], [], [], {}
    count = 0
    for tag, (name, quad, nx) in enumerate(structure(voussoirs), start=1):
        nz = 2 if nx > 1 else 1
        X, cells = hexes_of_prism(quad, depth, nx, nz)
        points.append(X)
        hexes.append(cells + count)
        tags += [tag] * len(cells)
        names[tag] = name
        count += len(X)
    return BlockMesh(np.concatenate(points), np.concatenate(hexes), np.array(tags), names)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--voussoirs", type=int, default=6, help="voussoirs of each half arch")
    parser.add_argument("--depth", type=float, default=0.3, help="depth along z (m)")
    parser.add_argument("-o", "--output", type=Path,
                        default=Path(__file__).with_name("pier_arches.msh"))
    args = parser.parse_args(argv)
    if args.voussoirs < 2 or not args.depth > 0:
        parser.error("--voussoirs must be at least 2 and --depth positive")
    mesh = pier_arches_mesh(args.voussoirs, args.depth)
    write_block_mesh(args.output, mesh)
    print(f"wrote {args.output}: {len(mesh.names)} blocks, {len(mesh.hexes)} hexahedra")


if __name__ == "__main__":
    main()
