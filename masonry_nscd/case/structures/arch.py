"""An arch of voussoirs on two abutments."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import ElementCount, Real, Section, Whole
from masonry_nscd.case.structures import Structure


class Arch(Section):
    """An arch of voussoirs on two abutments (``masonry_nscd/scenes/arch.py``), instead of a
    wall (lengths in m).

    The arch lies in the x-y plane: x horizontal from the middle of the span, y up from the
    springing line, z along its depth. ``radius_m`` is the radius of the arch's centreline
    (the middle of the ring), ``span_m`` the distance between the centres of its two springing
    joints. ``semicircular``: give one of them (span = 2 radius). ``pointed``: two arcs of
    ``radius_m`` whose centres lie on the springing line, ``radius - span / 2`` from the middle
    of the span on the other side, meeting at a vertical crown joint; give both, ``radius_m >
    span_m / 2``, and an even number of voussoirs.

    The joints between voussoirs are radial planes (a pointed arch's crown joint is vertical),
    equally spaced in angle; each voussoir is a prism on the chords of its intrados and
    extrados (one hexahedron, or ``elements_per_voussoir``). ``joint_thickness_m`` is the
    initial gap of every joint (0: dry voussoirs in contact). Abutments: ``fixed`` - the
    springers rest on two fixed rigid abutments; ``blocks`` - the abutments are rigid blocks
    (piers) of ``abutment_width_m`` x ``abutment_height_m`` resting on fixed ground through a
    joint of the joint law, free to slide and overturn.
    """

    shape: Literal["semicircular", "pointed"] = Field(
        "semicircular", description="semicircular, or pointed (two arcs meeting at the crown)"
    )
    radius_m: Real | None = Field(
        1.0, gt=0.0, le=1000.0,
        description="radius of the centreline (m; null: from span_m, semicircular arch)",
    )
    span_m: Real | None = Field(
        None, gt=0.0, le=2000.0,
        description="distance between the centres of the springing joints (m; null: 2 radius, "
        "semicircular arch)",
    )
    thickness_m: Real = Field(
        0.15, gt=0.0, le=100.0, description="thickness of the ring, intrados to extrados (m)"
    )
    depth_m: Real = Field(0.25, gt=0.0, le=100.0, description="depth of the arch along z (m)")
    voussoirs: Whole = Field(24, ge=3, le=500, description="number of voussoirs (count)")
    joint_thickness_m: Real = Field(
        0.0, ge=0.0, le=0.5, description="initial gap of every joint (m; 0: dry contact)"
    )
    elements_per_voussoir: tuple[ElementCount, ElementCount, ElementCount] = Field(
        (1, 1, 1),
        description="hexahedra per voussoir along the ring, through the thickness, along the "
        "depth (counts, 1..16 each)",
    )
    contact_points_per_face: Whole = Field(
        2, ge=1, le=4,
        description="contact points per direction on each element face in contact (count)",
    )
    contact_point_rule: Literal["auto", "gauss", "lobatto"] = Field(
        "auto",
        description="gauss, lobatto (the corners among them: voussoirs hinge about the edges "
        "of their faces) or auto: lobatto with 2 or more points, whatever the joint law",
    )
    abutments: Literal["fixed", "blocks"] = Field(
        "fixed", description="fixed (rigid supports) or blocks (rigid piers on fixed ground)"
    )
    abutment_width_m: Real | None = Field(
        None, gt=0.0, le=1000.0,
        description="width of each abutment along x, centred on its springing (m; null: 2 "
        "thickness)",
    )
    abutment_height_m: Real | None = Field(
        None, gt=0.0, le=1000.0,
        description="height of each abutment (m; null: the thickness)",
    )

    @property
    def centreline_radius_m(self) -> float:
        """Radius of the centreline (m)."""
        return float(self.radius_m if self.radius_m is not None else self.span_m / 2.0)

    @property
    def centreline_span_m(self) -> float:
        """Distance between the centres of the springing joints (m)."""
        return float(self.span_m if self.span_m is not None else 2.0 * self.radius_m)

    @model_validator(mode="after")
    def _check_geometry(self) -> Arch:
        problems: list[tuple[str, str]] = []
        if self.radius_m is None and self.span_m is None:
            problems.append(("radius_m", "give radius_m or span_m"))
        elif self.shape == "semicircular":
            if self.radius_m is not None and self.span_m is not None and \
                    abs(self.span_m - 2.0 * self.radius_m) > 1e-9 * self.span_m:
                problems.append(("span_m", (
                    f"got {self.span_m:.6g} m with radius_m = {self.radius_m:.6g} m; a "
                    "semicircular arch has span = 2 radius: give one of them")))
        else:
            if self.radius_m is None or self.span_m is None:
                problems.append(("span_m" if self.span_m is None else "radius_m",
                                 "a pointed arch needs both radius_m and span_m"))
            elif not self.radius_m > self.span_m / 2.0:
                problems.append(("radius_m", (
                    f"got {self.radius_m:.6g} m; a pointed arch needs radius_m > span_m / 2 = "
                    f"{self.span_m / 2.0:.6g} m (equal: semicircular)")))
            if self.voussoirs % 2:
                problems.append(("voussoirs", (
                    f"got {self.voussoirs}; a pointed arch needs an even number (its crown "
                    "is a joint)")))
        if not problems:
            r, t = self.centreline_radius_m, self.thickness_m
            c = r - self.centreline_span_m / 2.0
            if not r - t / 2.0 > c:
                problems.append(("thickness_m", (
                    f"got {t:.6g} m; the intrados radius (radius - thickness / 2) must exceed "
                    f"{'the offset of the centres ' if c > 0 else ''}{c:.6g} m: at most "
                    f"{2.0 * (r - c):.6g} m")))
            width = self.abutment_width_m
            if width is not None and width < t:
                problems.append(("abutment_width_m", (
                    f"got {width:.6g} m; an abutment must be at least as wide as the "
                    f"springing joint, the thickness {t:.6g} m")))
        raise_problems(problems)
        return self


def _point_load_problems(case) -> list[tuple[str, str]]:
    """A load or a removal naming a block the arch does not have (its voussoirs, from the
    left springing, and its block abutments)."""
    a = case.arch
    names = [f"voussoir {k}" for k in range(1, a.voussoirs + 1)]
    return point_load_problems(a, case.loading, names, f"voussoir 1 to voussoir {a.voussoirs}")


def named_block_problems(loading, names, how: str) -> list[tuple[str, str]]:
    """The blocks that the limit-state loads of ``loading`` name (``Loading.named_blocks``:
    the point load, the removal, the line loads) and that are not among ``names``, each
    ``(dotted path, text)``; ``how`` says how the blocks are named."""
    known = set(names)
    return [(path, f"got {name!r}; {how}") for path, name in loading.named_blocks()
            if name not in known]


def settlement_problems(case, names: tuple[str, ...]) -> list[tuple[str, str]]:
    """``loading.settlement.support`` against the supports ``names`` of the case's structure
    (none: the structure's supports do not move)."""
    settle = case.loading.settlement
    if settle is None or (settle.blocks is None and settle.support in names):
        return []
    what = case.structure.article
    if settle.blocks is not None:
        return [("loading.settlement.blocks", (
            f"given with {what} case; blocks name the support blocks of an assembly"
            + (f": give support, one of {', '.join(names)}" if names else
               f" ({what}'s supports are fixed)")))]
    if not names:
        return [("loading.settlement", f"given with {what} case, whose supports are fixed")]
    return [("loading.settlement.support", (
        f"got {settle.support!r}; the supports of {what} are " + ", ".join(names)))]


def _arch_problems(case) -> list[tuple[str, str]]:
    """A point load on a block the arch does not have, a support it does not have."""
    return _point_load_problems(case) + settlement_problems(case, ("left", "right"))


def point_load_problems(a: Arch, loading, names: list[str], where: str
                        ) -> list[tuple[str, str]]:
    """The blocks that the loads of ``loading`` name (the point load, the removal, the line
    loads) against the voussoirs ``names`` of the arch or vault ``a`` (``where``: how a
    message names their range) and its abutments when they are blocks."""
    extra = a.abutments == "blocks"
    if extra:
        names = [*names, "left abutment", "right abutment"]
    return named_block_problems(loading, names, (
        f"the blocks are {where} (from the left springing)"
        + (", left abutment, right abutment" if extra else "")))


#: The parts of a case that only a limit-state structure reads: its collapse rule and its
#: growing loads
LIMIT_STATE_OWNS = ("collapse", "loading.body_force", "loading.point_load",
                    "loading.settlement", "loading.removal", "loading.line_loads",
                    "loading.block_loads")

STRUCTURE = Structure(
    name="arch", model=Arch, article="an arch", order=10, limit_state=True,
    description="an arch of voussoirs instead of the wall (null: the wall)",
    owns=("arch", *LIMIT_STATE_OWNS), checks=_arch_problems)
