"""The element types a block mesh may use, found by their number of nodes or meshio's name.

One element type per block: a block's cells ``conn`` (nel, nodes) are all of the type whose
node count is ``conn.shape[1]``. A new element type is a module of its own that makes an
:class:`~masonry_nscd.fe.element.Element`, listed here (docs/architecture.md).
"""

from __future__ import annotations

import numpy as np

from masonry_nscd.fe.element import Element
from masonry_nscd.fe.hex8 import HEX8
from masonry_nscd.fe.tet4 import TET4
from masonry_nscd.fe.tet10 import TET10

ELEMENTS: tuple[Element, ...] = (HEX8, TET4, TET10)
_BY_NODES = {el.nodes: el for el in ELEMENTS}
BY_MESHIO = {el.meshio_type: el for el in ELEMENTS}


def element_of(conn: np.ndarray) -> Element:
    """The element type of cells ``conn`` (nel, nodes): by its number of nodes."""
    n = int(np.shape(conn)[1]) if np.ndim(conn) == 2 else -1
    el = _BY_NODES.get(n)
    if el is None:
        raise ValueError(f"cells of {n} nodes: a block is meshed with "
                         + ", ".join(f"{e.name} ({e.nodes} nodes)" for e in ELEMENTS))
    return el
