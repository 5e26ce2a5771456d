"""When a limit-state run has collapsed, and what is read of it."""

from __future__ import annotations

from pydantic import Field

from masonry_nscd.case.fields import Real, Section


class Collapse(Section):
    """When a limit-state run (an arch) has collapsed, and what is read of it
    (``masonry_nscd/post/limit.py``).

    A mechanism: the largest displacement of a point of a block passes ``displacement_m``, or,
    if it is given, the largest speed passes ``velocity_m_s``. The run then goes on for
    ``after_s`` and stops, with status ``collapse``; the loads at collapse are read at the
    onset of the mechanism, the last step before it at which every block was slower than
    ``onset_velocity_m_s`` or, if ``onset_kinetic_energy_J`` is given, at which the kinetic
    energy of the blocks was below it (for assemblies whose loosest stones rattle while the
    whole stands: a dry vault under a growing load). A run that reaches ``end_time_s`` stands
    (status ``standing``). A hinge is a joint open by more than ``hinge_opening_m`` over most
    of its face and closed at one edge.

    With supports that move (``loading.settlement``), the displacements and speeds are those
    relative to the supports' rigid motion: the small rigid motion that best fits the
    displacements of all the supports' nodes (least squares, each support weighing the same),
    taken out of every block point's motion. A settlement of one of two springings (a rotation
    about the other) or a common translation is then no collapse; what no rigid motion carries
    (a spreading of ``d``: ``d / 2`` at the blocks on the supports) and the structure's own
    deformation under it still count, so ``displacement_m`` must exceed those, not the
    settlement (``masonry_nscd/collapse.py``).
    """

    displacement_m: Real = Field(
        0.01, gt=0.0, le=100.0, description="a block point moved this far (relative to the supports' rigid motion "
        "when a support moves): collapse (m)"
    )
    velocity_m_s: Real | None = Field(
        None, gt=0.0, le=1000.0,
        description="a block point this fast: collapse (m/s; null: displacement only)",
    )
    onset_velocity_m_s: Real = Field(
        1e-3, gt=0.0, le=1000.0,
        description="slower than this, every block is at rest: the onset of the mechanism is "
        "the last such step (m/s)",
    )
    onset_kinetic_energy_J: Real | None = Field(
        None, gt=0.0, le=1e12,
        description="with less kinetic energy than this, the structure is at rest: the onset "
        "is the last such step, in place of onset_velocity_m_s (J; null: the speed decides)",
    )
    hinge_opening_m: Real = Field(
        1e-4, gt=0.0, le=10.0, description="a joint point opened by this much is open (m)"
    )
    end_time_s: Real = Field(
        2.0, gt=0.0, le=1e7, description="the run stops here if it has not collapsed (s)"
    )
    after_s: Real = Field(
        0.0, ge=0.0, le=1e6, description="time run on after the collapse is detected (s)"
    )


#: Sections of a case that belong to the wall builder and to the arch builder (the other's
#: are refused when given, and left out of the case written back).
