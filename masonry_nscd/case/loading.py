"""The loads: gravity, the wall's vertical stress and imposed displacement, a ground motion, and the growing loads and settlement of a limit state."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, PrivateAttr, ValidationInfo, field_validator, model_validator

from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import Direction, Real, Section, Vector3, Whole
from masonry_nscd.loading import histories as hs
from masonry_nscd.loading.ground_motion import GroundMotion, read_acceleration_record
from masonry_nscd.loading.histories import read_displacement_table


def _check_hold_after_start(hold_s: float | None, start_s: float) -> None:
    """A growing load is held after it has started (``hold_s > start_s``)."""
    if hold_s is not None and hold_s <= start_s:
        raise_problems([("hold_s", f"got {hold_s:g}; must be after start_s ({start_s:g} s)")])


class BodyForce(Section):
    """A body force ``lambda(t) g m`` on every block along ``direction`` (``g`` the gravity
    of ``loading.gravity``, ``m`` the block's mass): the pseudo-static seismic or tilting-table
    load, whose multiplier at collapse is the result. ``lambda`` rises to ``multiplier`` over
    the tanh ramp ``ramp_s`` from ``start_s``, and grows at ``rate_per_s`` from there on, its
    growth starting along the same ramp::

        lambda(t) = multiplier s(t) + rate_per_s ramp_s S((t - start_s) / ramp_s)

    (``s`` the ramp, ``S`` its integral, :mod:`masonry_nscd.loading.multiplier`). A horizontal
    body force of ``lambda`` with gravity is a base tilted by ``atan(lambda)``. With
    ``hold_s``, ``lambda`` stops growing there and keeps the value it reached: the load held,
    to see whether the structure comes to rest under it (status ``standing``) or collapses.
    """

    direction: Direction = Field(
        (1.0, 0.0, 0.0), description="direction of the body force: x, y, z (dimensionless, made a unit "
        "vector)"
    )
    multiplier: Real = Field(
        0.0, ge=-100.0, le=100.0,
        description="constant part of lambda, reached at start_s + ramp_s (dimensionless)",
    )
    rate_per_s: Real = Field(
        0.0, ge=0.0, le=1000.0, description="growth of lambda after the ramp (1/s; 0: none)"
    )
    start_s: Real = Field(0.3, ge=0.0, le=1e6, description="time at which the ramp starts (s)")
    ramp_s: Real = Field(0.1, gt=0.0, le=1e6, description="duration of the ramp (s)")
    hold_s: Real | None = Field(
        None, gt=0.0, le=1e6, description="time from which lambda is held at the value it "
        "reached (s, after start_s; null: it grows until the run ends)")

    @model_validator(mode="after")
    def _check_hold(self) -> BodyForce:
        _check_hold_after_start(self.hold_s, self.start_s)
        return self

    @property
    def active(self) -> bool:
        return self.multiplier != 0.0 or self.rate_per_s > 0.0


class PointLoad(Section):
    """A force on one block (``block``: its name, e.g. ``voussoir 7``) at the middle of its
    extrados face, ``force_N`` reached over the tanh ramp ``ramp_s`` from ``start_s`` and
    growing at ``rate_N_s`` from there on, held from ``hold_s`` if given (as ``lambda`` of
    ``body_force``)."""

    block: str = Field(..., min_length=1, max_length=200, description="name of the block")
    direction: Direction = Field(
        (0.0, -1.0, 0.0), description="direction of the force: x, y, z (dimensionless, made a unit vector)"
    )
    force_N: Real = Field(0.0, ge=0.0, le=1e12, description="constant part of the force (N)")
    rate_N_s: Real = Field(0.0, ge=0.0, le=1e12, description="growth of the force (N/s)")
    start_s: Real = Field(0.3, ge=0.0, le=1e6, description="time at which the ramp starts (s)")
    ramp_s: Real = Field(0.1, gt=0.0, le=1e6, description="duration of the ramp (s)")
    hold_s: Real | None = Field(
        None, gt=0.0, le=1e6, description="time from which the force is held at the value it "
        "reached (s, after start_s; null: it grows until the run ends)")

    @model_validator(mode="after")
    def _check_hold(self) -> PointLoad:
        _check_hold_after_start(self.hold_s, self.start_s)
        return self


class Removal(Section):
    """Blocks taken out of the structure at a time (a hole opened in a vault): ``blocks``, by
    name, leave the model at ``time_s``. From the start of the step in which ``time_s`` falls
    (exactly at ``time_s`` when it is on the grid of the time step) their contact points carry
    nothing (no impulse, no cohesion), their loads stop, the collapse rule no longer watches
    them, and the outputs flag them as removed; a rigid block is then held at rest where it
    was, a deformable one moves on with no contact and no load
    (:mod:`masonry_nscd.scenes.removal`). ``loading.removal`` is one such group, or a list of
    them, each with its own time (a block in one group only)."""

    blocks: list[Annotated[str, Field(min_length=1, max_length=200)]] = Field(
        ..., min_length=1, max_length=100000,
        description="names of the blocks removed (e.g. [voussoir 12])")
    time_s: Real = Field(
        ..., ge=0.0, le=1e6, description="time at which they leave the model (s; 0: before "
        "the first step)")

    @model_validator(mode="after")
    def _check_blocks(self) -> Removal:
        twice = sorted({b for b in self.blocks if self.blocks.count(b) > 1})
        if twice:
            raise_problems([("blocks", f"names {', '.join(map(repr, twice))} more than once")])
        return self


class LineLoad(Section):
    """A dead load spread along a segment over named blocks (fill, a wall on a vault): a force
    of ``force_N_m`` per metre of the segment from ``from_m`` to ``to_m`` (its resultant
    ``force_N_m`` times the segment's length), ramped with gravity. The segment is cut into
    short pieces; each piece's force acts at its middle on the named block under it, the
    highest of those whose outline in plan (x, z) holds the middle, or else the block nearest
    to it in plan (:func:`masonry_nscd.scenes.limit_loads.line_load_pattern`)."""

    blocks: list[Annotated[str, Field(min_length=1, max_length=200)]] = Field(
        ..., min_length=1, max_length=100000,
        description="names of the blocks that carry the load")
    force_N_m: Vector3 = Field(
        ..., description="force per metre of the segment (N/m): x, y, z (y up: a weight is "
        "[0, -w, 0])")
    from_m: Vector3 = Field(..., description="start of the segment (m): x, y, z")
    to_m: Vector3 = Field(..., description="end of the segment (m): x, y, z")

    @model_validator(mode="after")
    def _check_segment(self) -> LineLoad:
        if not sum((b - a) ** 2 for a, b in zip(self.from_m, self.to_m)) > 0.0:
            raise_problems([("to_m", "equals from_m; a line load needs a segment of length")])
        return self

    @property
    def length_m(self) -> float:
        """The segment's length (m)."""
        return sum((b - a) ** 2 for a, b in zip(self.from_m, self.to_m)) ** 0.5


class BlockLoad(Section):
    """A dead force on each of the named blocks (a column, a statue, a lantern's legs):
    ``force_N`` on every one of ``blocks``, where ``loading.point_load`` acts (the middle of
    the block's top or extrados face, the builder's), ramped with gravity."""

    blocks: list[Annotated[str, Field(min_length=1, max_length=200)]] = Field(
        ..., min_length=1, max_length=100000, description="names of the blocks loaded")
    force_N: Vector3 = Field(
        ..., description="force on each block (N): x, y, z (y up: a weight is [0, -W, 0])")


#: The names a support can have: an arch's springings, a cross vault's corners, and a cross
#: vault's sides (the two corners on that side)
SUPPORT_NAMES = ("left", "right", "north-east", "north-west", "south-east", "south-west",
                 "north", "south", "east", "west")


class Settlement(Section):
    """Supports that move: the fixed body under one springing of an arch or a barrel vault
    (the abutment, or the ground under a block abutment), the supports of a cross vault's
    corner or side (``east``: the two corners at +x; the spreading of a bay whose piers lean),
    or the support blocks of an assembly named in ``blocks`` (its foundations: the two piers
    of one side of a nave moving outwards), move by ``displacement_m`` along a tanh ramp of
    ``duration_s`` from ``start_s``. ``support`` names the support of an arch, a vault or a
    cross vault; ``blocks`` those of an assembly: one of the two."""

    support: Literal[SUPPORT_NAMES] | None = Field(  # type: ignore[valid-type]
        None, description="the support that moves: left or right (arch, vault); a corner "
        "(north-east, ...) or a side (north, south, east, west: its two corners) of a cross "
        "vault (null: blocks)")
    blocks: list[Annotated[str, Field(min_length=1, max_length=200)]] | None = Field(
        None, min_length=1, max_length=1000,
        description="assembly: the names of the support blocks that move (null: support)")
    displacement_m: Vector3 = Field(..., description="its displacement (m): x, y, z")
    start_s: Real = Field(0.3, ge=0.0, le=1e6, description="time at which it starts (s)")
    duration_s: Real = Field(1.0, gt=0.0, le=1e6, description="duration of the motion (s)")

    @model_validator(mode="after")
    def _one_of(self) -> Settlement:
        if (self.support is None) == (self.blocks is None):
            raise_problems([("support", (
                "give support (an arch's, a vault's or a cross vault's) or blocks (the "
                "support blocks of an assembly), one of them"))])
        if self.blocks is not None and len(set(self.blocks)) < len(self.blocks):
            raise_problems([("blocks", "a block is named twice")])
        return self

    @property
    def label(self) -> str:
        """How the outputs name what moves: ``the right support``, ``2 support blocks``."""
        if self.blocks is None:
            return f"the {self.support} support"
        return (f"the support block {self.blocks[0]!r}" if len(self.blocks) == 1 else
                f"{len(self.blocks)} support blocks")


class GravityStage(Section):
    """Gravity, ramped from 0 to ``value_m_s2`` (acceleration, m/s^2, acting in -y)."""

    value_m_s2: Real = Field(
        9.81, ge=0.0, le=1000.0, description="gravitational acceleration, downwards (m/s^2)"
    )
    start_s: Real = Field(0.0, ge=0.0, le=1e6, description="time at which the ramp starts (s)")
    ramp_s: Real = Field(0.05, gt=0.0, le=1e6, description="duration of the ramp (s)")


class StressStage(Section):
    """Vertical compressive stress sigma_N on the top beam, ramped from 0 to ``value_Pa``.

    ``value_Pa`` is a magnitude (>= 0): the force pushing the top beam down is
    ``value_Pa * wall_length_m * thickness_m`` (138.75 kN for 0.5 MPa over 1.85 x 0.15 m).
    """

    value_Pa: Real = Field(
        0.5e6,
        ge=0.0,
        le=1e9,
        description="compressive stress sigma_N over wall length x thickness, magnitude (Pa)",
    )
    start_s: Real = Field(0.05, ge=0.0, le=1e6, description="time at which the ramp starts (s)")
    ramp_s: Real = Field(0.15, gt=0.0, le=1e6, description="duration of the ramp (s)")


class HorizontalStage(Section):
    """Imposed horizontal displacement U_x of the top beam, along one of three histories
    (``history``; the equations are in :mod:`masonry_nscd.loading.histories`). The beam is
    driven through its velocity, each change of velocity a tanh ramp of ``ramp_s``.

    ``monotonic`` (the default, the study): the velocity ramps from 0 to ``rate_m_s`` over
    ``ramp_s`` from ``start_s``, then stays at ``rate_m_s``; the displacement therefore lags the
    ideal ``rate * (t - start)`` by ``rate_m_s * ramp_s / 2`` once the ramp is over. The run
    stops when U_x reaches ``target_m``, at ``start_s + ramp_s / 2 + target_m / rate_m_s``
    (:attr:`Loading.end_time_s`).

    ``cyclic``: for each amplitude A of ``amplitudes_m`` in turn, ``cycles_per_amplitude``
    cycles 0 -> +A -> -A -> 0 at the speed ``rate_m_s``, from ``start_s``; each reversal turns
    the velocity from +rate to -rate (or back) over ``ramp_s`` and stops exactly at +-A; the
    run ends when the beam is back at rest at 0 after the last cycle. Every amplitude must be
    at least ``rate_m_s * ramp_s`` (so that two ramps do not overlap). ``target_m`` is not
    used.

    ``table``: the displacement of the CSV file ``file`` (header ``time_s,displacement_m``,
    first row ``0,0``, times increasing; a relative path is relative to the case file's
    folder, and is written back resolved), linear between the rows, each row a corner rounded
    over ``ramp_s``; the table's time 0 is ``start_s + ramp_s / 2``; the run ends when the beam
    is at rest after the last row. ``target_m`` and ``rate_m_s`` are not used.

    ``none``: no horizontal push (the top beam is free in x); required with, and only with,
    ``loading.ground_motion``. The other fields are not used.
    """

    history: Literal["monotonic", "cyclic", "table", "none"] = Field(
        "monotonic", description="displacement history: monotonic (push to target_m), cyclic "
        "(amplitudes_m, cycles_per_amplitude), table (file), or none (no push: "
        "loading.ground_motion moves the base)"
    )
    target_m: Real = Field(
        0.010, gt=0.0, le=10.0,
        description="horizontal displacement at which the run stops (m; monotonic only)"
    )
    rate_m_s: Real = Field(
        0.002, gt=0.0, le=100.0,
        description="horizontal velocity after the ramp (m/s; monotonic and cyclic)"
    )
    start_s: Real = Field(0.25, ge=0.0, le=1e6, description="time at which the ramp starts (s)")
    ramp_s: Real = Field(
        0.05, gt=0.0, le=1e6,
        description="duration of each velocity ramp: start, reversals, corners (s)"
    )
    amplitudes_m: list[Annotated[Real, Field(gt=0.0, le=10.0)]] | None = Field(
        None, min_length=1, max_length=1000,
        description="cyclic: amplitudes of the cycles, in order (m; null otherwise)",
    )
    cycles_per_amplitude: Whole = Field(
        1, ge=1, le=100, description="cyclic: cycles at each amplitude (count)"
    )
    file: str | None = Field(
        None, min_length=1, max_length=4096,
        description="table: CSV file of time_s,displacement_m (relative to the case file; "
        "null otherwise)",
    )

    @field_validator("file")
    @classmethod
    def _resolve_file(cls, value: str | None, info: ValidationInfo) -> str | None:
        """A relative path is made absolute from the case file's folder (validation context
        ``case_dir``), so that the case written back in the run folder still finds it."""
        base = (info.context or {}).get("case_dir")
        if value is None or base is None or Path(value).is_absolute():
            return value
        return str((Path(base) / value).resolve())

    @model_validator(mode="after")
    def _check_history(self, info: ValidationInfo) -> HorizontalStage:
        problems: list[tuple[str, str]] = []
        kind = self.history
        if kind != "cyclic" and self.amplitudes_m is not None:
            problems.append(("amplitudes_m", (
                f"given with history '{kind}'; amplitudes are for history 'cyclic' (set "
                "history: cyclic, or leave amplitudes_m out)")))
        if kind != "table" and self.file is not None:
            problems.append(("file", (
                f"given with history '{kind}'; a file is for history 'table' (set "
                "history: table, or leave file out)")))
        if kind == "cyclic":
            if self.amplitudes_m is None:
                problems.append(("amplitudes_m", (
                    "missing; history 'cyclic' needs the list of amplitudes (m), e.g. "
                    "[0.001, 0.002, 0.004]")))
            elif min(self.amplitudes_m) < self.rate_m_s * self.ramp_s:
                problems.append(("amplitudes_m", (
                    f"got {min(self.amplitudes_m):.6g} m; every amplitude must be at least "
                    f"rate_m_s x ramp_s = {self.rate_m_s * self.ramp_s:.6g} m (a reversal "
                    "takes ramp_s): lower ramp_s or rate_m_s")))
        if kind == "table":
            if self.file is None:
                problems.append(("file", (
                    "missing; history 'table' needs a CSV file of time_s,displacement_m")))
            elif (info.context or {}).get("check_files"):
                try:
                    self._table = read_displacement_table(self.file)
                except ValueError as exc:
                    problems.append(("file", str(exc)))
        raise_problems(problems)
        return self

    _table: Any = PrivateAttr(None)

    def displacement_history(self):
        """The history (:class:`masonry_nscd.loading.histories.DisplacementHistory`): the
        beam's velocity, the end of the motion, the cycles. A table is read from ``file``
        (ValueError naming the file and line if it cannot be). None for ``none``."""
        if self.history == "cyclic":
            return hs.cyclic(self.amplitudes_m, self.cycles_per_amplitude, self.rate_m_s,
                             self.start_s, self.ramp_s)
        if self.history == "table":
            if self._table is None:
                self._table = hs.read_displacement_table(self.file)
            return hs.table(*self._table, self.start_s, self.ramp_s)
        if self.history == "none":
            return None
        return hs.monotonic(self.rate_m_s, self.start_s, self.ramp_s)


class GroundMotionStage(Section):
    """An acceleration record applied to the base (:mod:`masonry_nscd.loading.ground_motion`):
    the lower beam moves along ``direction`` with the record times ``scale`` integrated to its
    velocity and displacement (piecewise-linear acceleration between the rows), the record's
    time 0 at ``start_s``. ``file``: a CSV file with the header ``time_s,acceleration_m_s2``
    (s, m/s^2), first time 0, times increasing; a relative path is relative to the case file's
    folder and is written back resolved. The run ends at the record's last row (give the
    record a quiet tail for the wall to come to rest: the residual drift is read at the end).
    With a ground motion, ``loading.horizontal.history`` must be ``none``.
    """

    file: str = Field(
        min_length=1, max_length=4096,
        description="CSV file of time_s,acceleration_m_s2 (relative to the case file)",
    )
    scale: Real = Field(
        1.0, gt=0.0, le=100.0, description="factor on the record's accelerations (dimensionless)"
    )
    direction: Literal["x", "y"] = Field(
        "x", description="direction of the base motion: x (horizontal, in the wall's plane) or "
        "y (vertical)"
    )
    start_s: Real = Field(
        0.25, ge=0.0, le=1e6, description="run time of the record's time 0 (s)"
    )

    @field_validator("file")
    @classmethod
    def _resolve_file(cls, value: str, info: ValidationInfo) -> str:
        """A relative path is made absolute from the case file's folder (validation context
        ``case_dir``), as ``loading.horizontal.file``."""
        base = (info.context or {}).get("case_dir")
        if base is None or Path(value).is_absolute():
            return value
        return str((Path(base) / value).resolve())

    @model_validator(mode="after")
    def _check_file(self, info: ValidationInfo) -> GroundMotionStage:
        if (info.context or {}).get("check_files"):
            try:  # read to check it only: nothing kept, so the case compares equal to a
                # copy read without its files
                read_acceleration_record(self.file)
            except ValueError as exc:
                raise_problems([("file", str(exc))])
        return self

    def history(self):
        """The base's motion (:class:`masonry_nscd.loading.ground_motion.GroundMotion`),
        scaled; the record read from ``file`` at each call (ValueError naming the file and
        line if it cannot be)."""
        t, a = read_acceleration_record(self.file)
        return GroundMotion(t, self.scale * a, self.start_s)


class Loading(Section):
    """The three load stages, each ramped smoothly: gravity, then the vertical stress, then the
    horizontal displacement (the stages may overlap; the study applies them one after the other).
    """

    gravity: GravityStage = Field(default_factory=GravityStage, description="gravity stage")
    vertical_stress: StressStage = Field(
        default_factory=StressStage, description="vertical compressive stress on the top beam"
    )
    horizontal: HorizontalStage = Field(
        default_factory=HorizontalStage, description="imposed horizontal displacement"
    )
    ground_motion: GroundMotionStage | None = Field(
        None, description="acceleration record applied to the base (null: none)"
    )
    # the loads of limit-state runs (an arch, a vault, an assembly; this module's top)
    body_force: BodyForce = Field(
        default_factory=BodyForce,
        description="limit states: body force lambda(t) g m along a direction (the collapse "
        "multiplier)",
    )
    point_load: PointLoad | None = Field(
        None, description="limit states: a growing force on one block (null: none)"
    )
    settlement: Settlement | None = Field(
        None, description="arch, vault, cross vault, assembly: the settlement of supports (null: "
        "none)"
    )
    removal: Removal | list[Removal] | None = Field(
        None, description="limit states: blocks taken out at a time, or a list of such "
        "groups, each at its time (null: none)"
    )
    line_loads: list[LineLoad] = Field(
        default_factory=list, max_length=1000,
        description="limit states: dead loads per metre along segments over named blocks"
    )
    block_loads: list[BlockLoad] = Field(
        default_factory=list, max_length=1000,
        description="limit states: dead forces on named blocks, the same on each"
    )

    def named_blocks(self) -> list[tuple[str, str]]:
        """Every block a limit-state load names, as ``(dotted path, name)``: the point load's,
        the removed blocks, the line and block loads' blocks (the builders check them against
        theirs)."""
        out = []
        if self.point_load is not None:
            out.append(("loading.point_load.block", self.point_load.block))
        for path, group in self.removal_groups():
            out += [(f"{path}.blocks[{i}]", b) for i, b in enumerate(group.blocks)]
        for field in ("line_loads", "block_loads"):
            for k, load in enumerate(getattr(self, field)):
                out += [(f"loading.{field}[{k}].blocks[{i}]", b)
                        for i, b in enumerate(load.blocks)]
        return out

    def removal_groups(self) -> list[tuple[str, Removal]]:
        """The groups of ``removal``, each with its dotted path: ``loading.removal`` for the
        single form, ``loading.removal[k]`` for a list (none without a removal)."""
        if self.removal is None:
            return []
        if isinstance(self.removal, Removal):
            return [("loading.removal", self.removal)]
        return [(f"loading.removal[{k}]", group) for k, group in enumerate(self.removal)]

    @model_validator(mode="after")
    def _check_removals(self) -> Loading:
        """A list of removals is not empty, and each block leaves once."""
        if isinstance(self.removal, list) and not self.removal:
            raise_problems([("removal", "an empty list; give null for no removal")])
        first: dict[str, str] = {}
        problems = []
        for path, group in self.removal_groups():
            for i, name in enumerate(group.blocks):
                if name in first and first[name] != path:
                    problems.append((f"{path}.blocks[{i}]".removeprefix("loading."), (
                        f"got {name!r}, already removed by {first[name]}")))
                first.setdefault(name, path)
        raise_problems(problems)
        return self

    @property
    def end_time_s(self) -> float:
        """Expected end of the run (s). Monotonic: ``start + ramp / 2 + target / rate`` of the
        horizontal stage, when U_x reaches ``target_m`` (the velocity ramps to ``rate_m_s``
        over ``ramp_s``, so the displacement lags the sharp path by ``rate ramp / 2``; exact
        when ``target_m`` is reached after the ramp, ``loading.RampedVelocity``). Cyclic and
        table: the end of the motion, when the run stops. Ground motion: the end of the
        record."""
        if self.ground_motion is not None:
            return float(self.ground_motion.history().end_s)
        h = self.horizontal
        if h.history == "none":
            return h.start_s
        if h.history != "monotonic":
            return float(h.displacement_history().end_s)
        return h.start_s + h.ramp_s / 2.0 + h.target_m / h.rate_m_s
