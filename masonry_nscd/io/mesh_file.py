r"""Block meshes read from a mesh file (Gmsh ``.msh``, or any format meshio reads), and written.

The only module that imports meshio (barely maintained); the VTU output is written without it.

A **block mesh** is a set of elements (8-node hexahedra, 4- and 10-node tetrahedra: meshio's
``hexahedron``, ``tetra`` and ``tetra10``), each with an integer tag: the elements of one tag
are one block, all of one type (a file may mix blocks of different types). In a Gmsh file the tag is the element's physical group (meshio's cell data
``gmsh:physical``) and the block's name the physical group's name (``$PhysicalNames``, meshio's
``field_data``: name -> (tag, dimension)); in another format the tag is a cell data array
named by the caller. Node order: VTK's and Gmsh's (the same for the linear hexahedron), which
is :mod:`masonry_nscd.fe.hex8`'s: the bottom face counter-clockwise seen from above, then the
top face; VTK's for tetrahedra (meshio puts Gmsh's 10-node tetrahedra in it). Coordinates in m.

Lower-dimensional cells (vertices, lines, triangles, quadrilaterals: Gmsh's physical points,
curves and surfaces) are left out; other 3D cells (wedges, pyramids, 20-node hexahedra) are
refused.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: Gmsh's physical tags in meshio's cell data.
GMSH_PHYSICAL = "gmsh:physical"
_SOLID = ("wedge", "pyramid", "hexahedron20", "hexahedron27", "wedge15", "pyramid13",
          "polyhedron")
#: meshio's cell types of the elements a block may be meshed with, and their element names
ELEMENT_TYPES = {"hexahedron": "hex8", "tetra": "tet4", "tetra10": "tet10"}


class MeshFileError(ValueError):
    """A mesh file that cannot be read as a block mesh (the message names the file)."""


@dataclass
class BlockMesh:
    """Elements with a block tag each (module docstring): the hexahedra, and the cells of
    other types (``others``: meshio's cell type -> (cells, tags))."""

    points: np.ndarray  # (n, 3) m
    hexes: np.ndarray  # (e, 8) node numbers
    tags: np.ndarray  # (e,) block tag of each hexahedron
    names: dict[int, str] = field(default_factory=dict)  # tag -> name (Gmsh physical names)
    others: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)

    def block_name(self, tag: int) -> str:
        """The block's name: its physical name, or ``block <tag>``."""
        return self.names.get(int(tag), f"block {int(tag)}")

    def cell_sets(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """``(meshio type, cells, tags)`` of each element type present, hexahedra first."""
        sets = [("hexahedron", self.hexes, self.tags)] if len(self.hexes) else []
        return sets + [(t, c, g) for t, (c, g) in self.others.items() if len(c)]

    def block_tags(self) -> np.ndarray:
        """The tags of the blocks, sorted."""
        return np.unique(np.concatenate([g for _, _, g in self.cell_sets()] or [[]])
                         ).astype(np.int64)

    def block_cells(self, tag: int) -> np.ndarray:
        """The cells (e, nodes) of block ``tag``; MeshFileError when they are of two types."""
        found = [(t, c[g == tag]) for t, c, g in self.cell_sets() if np.any(g == tag)]
        if len(found) > 1:
            raise MeshFileError(f"{self.block_name(tag)!r}: cells of "
                                f"{' and '.join(t for t, _ in found)}; a block is meshed "
                                "with one element type")
        return found[0][1] if found else np.zeros((0, 8), dtype=np.int64)


def read_block_mesh(path: str | Path, tag_field: str = GMSH_PHYSICAL) -> BlockMesh:
    """The block mesh of ``path`` (MeshFileError when it cannot be read, has no hexahedra or
    tetrahedra, has other solid cells, or no ``tag_field`` on its elements)."""
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
    cells: dict[str, list] = {t: [] for t in ELEMENT_TYPES}
    tags: dict[str, list] = {t: [] for t in ELEMENT_TYPES}
    for j, block in enumerate(mesh.cells):
        if block.type in _SOLID:
            raise MeshFileError(
                f"{path}: {len(block.data)} {block.type} cells; blocks are meshed with 8-node "
                "hexahedra or 4- or 10-node tetrahedra only")
        if block.type not in ELEMENT_TYPES:
            continue
        data = mesh.cell_data.get(tag_field)
        if data is None:
            raise MeshFileError(
                f"{path}: its {block.type} cells have no cell data {tag_field!r} (the block of "
                f"each element); it has {sorted(mesh.cell_data) or 'none'}")
        cells[block.type].append(np.asarray(block.data, dtype=np.int64))
        tags[block.type].append(np.asarray(data[j], dtype=np.int64).ravel())
    if not any(cells.values()):
        raise MeshFileError(f"{path}: no hexahedra or tetrahedra (cell types: "
                            f"{', '.join(sorted({b.type for b in mesh.cells})) or 'none'})")

    def joined(t: str) -> tuple[np.ndarray, np.ndarray]:
        nodes = {"hexahedron": 8, "tetra": 4, "tetra10": 10}[t]
        return (np.concatenate(cells[t]) if cells[t] else np.zeros((0, nodes), dtype=np.int64),
                np.concatenate(tags[t]) if tags[t] else np.zeros(0, dtype=np.int64))

    names = {int(v[0]): str(k) for k, v in (mesh.field_data or {}).items()
             if len(np.ravel(v)) >= 2 and int(np.ravel(v)[1]) == 3}
    points = np.asarray(mesh.points, dtype=float)
    if points.shape[1] == 2:
        raise MeshFileError(f"{path}: 2D points; a block mesh is 3D")
    hexes, hex_tags = joined("hexahedron")
    others = {t: joined(t) for t in ("tetra", "tetra10") if cells[t]}
    return BlockMesh(points[:, :3], hexes, hex_tags, names, others)


def write_block_mesh(path: str | Path, mesh: BlockMesh) -> None:
    """Write ``mesh`` as a Gmsh 2.2 ASCII ``.msh`` (physical names, one physical volume per
    block; hexahedra, then the tetrahedra), which Gmsh and meshio read."""
    import meshio

    sets = mesh.cell_sets()
    tags = [np.asarray(g, dtype=np.int64) for _, _, g in sets]
    out = meshio.Mesh(np.asarray(mesh.points, dtype=float),
                      [(t, np.asarray(c, dtype=np.int64)) for t, c, _ in sets],
                      cell_data={GMSH_PHYSICAL: tags, "gmsh:geometrical": tags},
                      field_data={name: np.array([tag, 3]) for tag, name in mesh.names.items()})
    meshio.write(path, out, file_format="gmsh22", binary=False)
