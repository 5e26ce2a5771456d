r"""Block meshes read from a mesh file (Gmsh ``.msh``, or any format meshio reads), and written.

The only module that imports meshio (barely maintained); the VTU output is written without it.

A **block mesh** is a set of 8-node hexahedra, each with an integer tag: the hexahedra of one
tag are one block. In a Gmsh file the tag is the element's physical group (meshio's cell data
``gmsh:physical``) and the block's name the physical group's name (``$PhysicalNames``, meshio's
``field_data``: name -> (tag, dimension)); in another format the tag is a cell data array
named by the caller. Node order: VTK's and Gmsh's (the same for the linear hexahedron), which
is :mod:`masonry_nscd.fe.hex8`'s: the bottom face counter-clockwise seen from above, then the
top face. Coordinates in m.

Lower-dimensional cells (vertices, lines, triangles, quadrilaterals: Gmsh's physical points,
curves and surfaces) are left out; other 3D cells (tetrahedra, wedges, pyramids) are refused:
a block is meshed with hexahedra.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: Gmsh's physical tags in meshio's cell data.
GMSH_PHYSICAL = "gmsh:physical"
_SOLID = ("tetra", "wedge", "pyramid", "tetra10", "hexahedron20", "hexahedron27", "wedge15",
          "pyramid13", "polyhedron")


class MeshFileError(ValueError):
    """A mesh file that cannot be read as a block mesh (the message names the file)."""


@dataclass
class BlockMesh:
    """Hexahedra with a block tag each (module docstring)."""

    points: np.ndarray  # (n, 3) m
    hexes: np.ndarray  # (e, 8) node numbers
    tags: np.ndarray  # (e,) block tag of each hexahedron
    names: dict[int, str] = field(default_factory=dict)  # tag -> name (Gmsh physical names)

    def block_name(self, tag: int) -> str:
        """The block's name: its physical name, or ``block <tag>``."""
        return self.names.get(int(tag), f"block {int(tag)}")


def read_block_mesh(path: str | Path, tag_field: str = GMSH_PHYSICAL) -> BlockMesh:
    """The block mesh of ``path`` (MeshFileError when it cannot be read, has no hexahedra,
    has other solid cells, or no ``tag_field`` on its hexahedra)."""
    import meshio

    path = Path(path)
    if not path.is_file():
        raise MeshFileError(f"{path}: mesh file not found")
    try:
        mesh = meshio.read(path)
    except (meshio.ReadError, OSError, ValueError, KeyError, IndexError, TypeError,
            AssertionError, UnicodeDecodeError) as exc:  # meshio's readers raise these
        raise MeshFileError(f"{path}: cannot read it as a mesh: {type(exc).__name__}: "
                            f"{exc}") from None
    hexes, tags = [], []
    for j, block in enumerate(mesh.cells):
        if block.type in _SOLID:
            raise MeshFileError(
                f"{path}: {len(block.data)} {block.type} cells; blocks are meshed with 8-node "
                "hexahedra only (recombine the mesh into hexahedra)")
        if block.type != "hexahedron":
            continue
        data = mesh.cell_data.get(tag_field)
        if data is None:
            raise MeshFileError(
                f"{path}: its hexahedra have no cell data {tag_field!r} (the block of each "
                f"element); it has {sorted(mesh.cell_data) or 'none'}")
        hexes.append(np.asarray(block.data, dtype=np.int64))
        tags.append(np.asarray(data[j], dtype=np.int64).ravel())
    if not hexes:
        raise MeshFileError(f"{path}: no hexahedra (cell types: "
                            f"{', '.join(sorted({b.type for b in mesh.cells})) or 'none'})")
    names = {int(v[0]): str(k) for k, v in (mesh.field_data or {}).items()
             if len(np.ravel(v)) >= 2 and int(np.ravel(v)[1]) == 3}
    points = np.asarray(mesh.points, dtype=float)
    if points.shape[1] == 2:
        raise MeshFileError(f"{path}: 2D points; a block mesh is 3D")
    return BlockMesh(points[:, :3], np.concatenate(hexes), np.concatenate(tags), names)


def write_block_mesh(path: str | Path, mesh: BlockMesh) -> None:
    """Write ``mesh`` as a Gmsh 2.2 ASCII ``.msh`` (physical names, one physical volume per
    block), which Gmsh and meshio read."""
    import meshio

    tags = np.asarray(mesh.tags, dtype=np.int64)
    out = meshio.Mesh(np.asarray(mesh.points, dtype=float),
                      [("hexahedron", np.asarray(mesh.hexes, dtype=np.int64))],
                      cell_data={GMSH_PHYSICAL: [tags], "gmsh:geometrical": [tags]},
                      field_data={name: np.array([tag, 3]) for tag, name in mesh.names.items()})
    meshio.write(path, out, file_format="gmsh22", binary=False)
