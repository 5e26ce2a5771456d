"""The block assembly: bodies with meshes (hexahedra or tetrahedra), their faces, the joints
found between them and the contact points that sample the joints. Nothing here integrates in
time.

Scene builders (:mod:`masonry_nscd.scenes`) make the bodies; :mod:`~masonry_nscd.model.detection`
finds the joints and places their contact points; ``nscd.system.build_system`` numbers the dofs
and packs everything into the flat arrays of the kernels.
"""

from masonry_nscd.model.bodies import (
    DOF_FREE,
    DOF_IMPOSED,
    MAT_ELASTIC,
    MAT_ENDO3D,
    Block,
    RigidBody,
    body_mass,
    body_momentum,
)
from masonry_nscd.model.points import ContactPoint, dof_offsets

__all__ = ["DOF_FREE", "DOF_IMPOSED", "MAT_ELASTIC", "MAT_ENDO3D", "Block", "ContactPoint",
           "RigidBody", "body_mass", "body_momentum", "dof_offsets"]
