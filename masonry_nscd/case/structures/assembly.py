"""A block assembly read from a mesh file: its supports and the materials of its blocks."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import Real, Section, Whole
from masonry_nscd.case.structures import Structure
from masonry_nscd.case.structures.arch import LIMIT_STATE_OWNS

GroupRef = Annotated[Whole | str, Field(union_mode="left_to_right")]


class AssemblySupport(Section):
    """A block of the mesh that is a support: fixed (it does not move), its joints with the
    structure of the joint law (``fixed``) or glued (``glued``: no opening, no slip)."""

    group: GroupRef = Field(..., description="the block: its physical name or its tag")
    kind: Literal["fixed", "glued"] = Field(
        "fixed", description="fixed (joints of the joint law) or glued (glued joints)"
    )


class AssemblyMaterial(Section):
    """The material of one block of the mesh (null fields: those of ``blocks``)."""

    group: GroupRef = Field(..., description="the block: its physical name or its tag")
    material: Literal["rigid", "elastic"] = Field("rigid", description="rigid or elastic")
    density_kg_m3: Real | None = Field(
        None, ge=100.0, le=1e5, description="density (kg/m^3; null: blocks.density_kg_m3)"
    )
    E_Pa: Real | None = Field(
        None, ge=1e6, le=1e13, description="Young's modulus (Pa; null: blocks.E_Pa)"
    )
    nu: Real | None = Field(
        None, gt=-1.0, lt=0.5, description="Poisson's ratio (dimensionless; null: blocks.nu)"
    )


class Assembly(Section):
    """A block assembly read from a mesh file (``masonry_nscd/scenes/assembly.py``), instead
    of a wall, an arch or a vault.

    ``mesh_file``: a mesh of 8-node hexahedra (Gmsh ``.msh``, or any format meshio reads; a
    relative path is relative to the case file); the hexahedra of one tag (``tag_field``:
    Gmsh's physical group) are one block, named by its physical name (or ``block <tag>``).
    ``supports`` name the blocks that are fixed supports (at least one); ``materials`` give a
    block's material by its name or tag, the others take ``blocks``. Joints are found by the
    generic contact detection between facing faces at most ``joint_thickness_m`` apart (groups
    ``joint``, ``support``, ``glue``) and follow ``joint``. y is up (gravity along -y). The
    mesh file is read and its groups checked by the builder (``scenes/assembly.py``).
    """

    mesh_file: str = Field(
        ..., min_length=1, max_length=4096,
        description="mesh file of hexahedra (relative to the case file)",
    )
    tag_field: str = Field(
        "gmsh:physical", min_length=1, max_length=200,
        description="cell data of the block tag of each hexahedron",
    )
    supports: list[AssemblySupport] = Field(
        ..., min_length=1, max_length=1000, description="the blocks that are supports"
    )
    materials: list[AssemblyMaterial] = Field(
        default_factory=list, max_length=100_000,
        description="material of a block by name or tag (the others: blocks)",
    )
    driven_block: str | None = Field(
        None, max_length=200,
        description="block whose displacement is the curve's ux, uy (null: the highest)",
    )
    joint_thickness_m: Real = Field(
        0.0, ge=0.0, le=0.5, description="largest gap between two faces of a joint (m)"
    )
    contact_points_per_face: Whole = Field(
        2, ge=1, le=4,
        description="contact points per direction on each element face in contact (count)",
    )
    contact_point_rule: Literal["auto", "gauss", "lobatto", "overlap"] = Field(
        "auto", description="gauss, lobatto, overlap (on the common area of two faces, at its "
        "corners between rigid blocks: faces that meet in part, a block on two) or auto: "
        "lobatto with 2 or more points"
    )

    @field_validator("mesh_file")
    @classmethod
    def _resolve_file(cls, value: str, info: ValidationInfo) -> str:
        """A relative path is made absolute from the case file's folder, as
        ``loading.ground_motion.file``."""
        base = (info.context or {}).get("case_dir")
        if base is None or Path(value).is_absolute():
            return value
        return str((Path(base) / value).resolve())

    @model_validator(mode="after")
    def _check_groups(self) -> Assembly:
        problems: list[tuple[str, str]] = []
        seen: dict[str, str] = {}
        for table in ("supports", "materials"):
            for i, entry in enumerate(getattr(self, table)):
                key = str(entry.group)
                if key in seen and (table == "supports" or seen[key] == table):
                    problems.append((f"{table}[{i}].group", (
                        f"got {entry.group!r} again; a block is named once in {table}"
                        + (" and once in materials" if table == "supports" else ""))))
                seen.setdefault(key, table)
        raise_problems(problems)
        return self


def _settlement_problems(case) -> list[tuple[str, str]]:
    """An assembly's settlement names its support blocks (``blocks``; which are supports is
    the builder's check, it reads the mesh), not an arch's or a cross vault's ``support``."""
    settle = case.loading.settlement
    if settle is None or settle.blocks is not None:
        return []
    return [("loading.settlement.support", (
        f"got {settle.support!r}; an assembly's settlement names the support blocks that "
        "move: loading.settlement.blocks: [names of blocks in assembly.supports]"))]


STRUCTURE = Structure(
    name="assembly", model=Assembly, article="an assembly", order=30, limit_state=True,
    description="blocks from a mesh file instead of the wall (null: the wall)",
    owns=("assembly", *LIMIT_STATE_OWNS), checks=_settlement_problems)
