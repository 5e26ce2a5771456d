"""A barrel vault: the arch in rings of voussoirs along its depth."""

from __future__ import annotations

from pydantic import Field, model_validator

from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import Real, Whole
from masonry_nscd.case.structures import Structure
from masonry_nscd.case.structures.arch import (
    LIMIT_STATE_OWNS,
    Arch,
    point_load_problems,
    settlement_problems,
)


class Vault(Arch):
    """A barrel vault (``masonry_nscd/scenes/vault.py``): the arch of the same fields extruded
    along z over ``depth_m``, in ``rings`` rings of voussoirs side by side, each
    ``depth_m / rings`` deep, instead of a wall or an arch.

    With ``stagger`` the radial joints of every second ring fall in the middle of the voussoirs
    of its neighbours (running bond along the ring): that ring has ``voussoirs - 1`` whole
    voussoirs and a half voussoir at each springing. The joints between rings are planes
    ``z = const``; every joint is a dry contact (``joint_thickness_m`` must be 0). The
    abutments run along the whole depth. A voussoir is made of two half voussoirs (one at a
    staggered ring's springings), each meshed with ``elements_per_voussoir`` hexahedra.
    """

    depth_m: Real = Field(1.0, gt=0.0, le=100.0, description="length of the vault along z (m)")
    rings: Whole = Field(4, ge=1, le=100, description="rings of voussoirs along z (count)")
    stagger: bool = Field(
        True, description="radial joints of every second ring offset by half a voussoir"
    )

    @model_validator(mode="after")
    def _check_vault(self) -> Vault:
        problems: list[tuple[str, str]] = []
        if self.joint_thickness_m != 0.0:
            problems.append(("joint_thickness_m", (
                f"got {self.joint_thickness_m:.6g} m; a vault's joints are dry contacts: 0 (the "
                "corners of a staggered ring would fall into a gap of its neighbour)")))
        raise_problems(problems)
        return self

    def staggered(self, ring: int) -> bool:
        """Whether ring ``ring`` (from 1) is staggered: every second one, with ``stagger``."""
        return bool(self.stagger) and ring % 2 == 0

    def ring_voussoirs(self, ring: int) -> int:
        """How many voussoirs ring ``ring`` (from 1) has: ``voussoirs``, one more in a staggered
        ring (a half voussoir at each springing)."""
        return self.voussoirs + (1 if self.staggered(ring) else 0)

    def voussoir_names(self, ring: int | None = None) -> list[str]:
        """The names of the voussoirs of ring ``ring`` (from 1), or of every ring."""
        rings = range(1, self.rings + 1) if ring is None else [ring]
        return [f"ring {i} voussoir {k + 1}" for i in rings
                for k in range(self.ring_voussoirs(i))]


def _point_load_problems(case) -> list[tuple[str, str]]:
    """A point load on a block the vault does not have."""
    v = case.vault
    moved = settlement_problems(case, ("left", "right"))
    where = (f"ring 1 voussoir 1 to ring {v.rings} voussoir "
             f"{len(v.voussoir_names(v.rings))}")
    return point_load_problems(v, case.loading, v.voussoir_names(), where) + moved


STRUCTURE = Structure(
    name="vault", model=Vault, article="a vault", order=20, limit_state=True,
    description="a barrel vault instead of the wall (null: the wall or the arch)",
    owns=("vault", *LIMIT_STATE_OWNS), checks=_point_load_problems)
