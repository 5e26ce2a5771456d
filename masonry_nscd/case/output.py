"""What a run writes, and how often."""

from __future__ import annotations

from pydantic import Field

from masonry_nscd.case.fields import Section, Whole


class Output(Section):
    """What the run writes (the force-displacement CSV is always written, every step)."""

    every_steps: Whole = Field(
        5, ge=1, le=1_000_000_000, description="write fields every this many steps of "
        "solver.time_step_s (count; with adaptive steps, the largest step divides it)"
    )
    vtu: bool = Field(True, description="write VTU/PVD fields for ParaView (true/false)")
    hdf5: bool = Field(True, description="write results.h5 (true/false)")
    energy: bool = Field(
        True, description="compute the energy balance and write energy.csv (true/false)"
    )
