"""The joint law: the frictional cohesive zone in series with a spring, or Coulomb; its scatter and its regions."""

from __future__ import annotations

import math
from typing import Annotated, ClassVar, Literal

from pydantic import Field, ValidationError, model_validator

from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import Real, Section, Whole
from masonry_nscd.case.messages import messages


class JointScatter(Section):
    """Scatter of the joint properties (masonry_nscd/contact/scatter.py): each of ``fields``
    drawn independently from a lognormal law whose mean is the case's value and whose
    coefficient of variation is ``cv``, once per joint (``per: joint``, the interface between
    two units) or per element face of the joint (``per: face``), with the random ``seed``. The
    glue is not scattered."""

    cv: Real = Field(0.2, gt=0.0, le=2.0, description="coefficient of variation (dimensionless)")
    seed: Whole = Field(1, ge=0, le=2**63 - 1, description="seed of the random draws (index)")
    fields: list[Literal["sigma_I_e_Pa", "sigma_II_e_Pa", "G_fI_J_m2", "G_fII_J_m2"]] = Field(
        default_factory=lambda: ["sigma_I_e_Pa", "sigma_II_e_Pa", "G_fI_J_m2", "G_fII_J_m2"],
        min_length=1, max_length=4, description="joint fields drawn",
    )
    per: Literal["joint", "face"] = Field(
        "joint", description="one draw per joint (two units) or per element face of a joint"
    )


#: The numbers of the fczm law a joint region may set; the law itself, the spring convention in
#: compression and the scatter are the case's.
REGION_FIELDS = ("K_I_spring_Pa_m", "K_II_spring_Pa_m", "d_spring", "sigma_I_e_Pa",
                 "K_I_coh_Pa_m", "G_fI_J_m2", "sigma_II_e_Pa", "K_II_coh_Pa_m", "G_fII_J_m2",
                 "d_coh_initial", "mu", "p", "eta")


class JointRegion(Section):
    """Joints of a wall with properties of their own (``joint.regions``): the bed joints on
    top of the courses ``courses`` (``joints: bed``; course 1: the joint between the first and
    the second course, the study's base joint) or the head joints within them (``joints:
    head``). Courses count from 1 at the bottom, negative from the top (-1: the top course);
    null: every course. Each field given replaces the case's value for those joints (bounds and
    fracture-energy checks as in ``joint``); the others are the case's. Example, a base joint
    with 0.3 times the others' strengths (the energies times 0.3^2 keep the shape of the
    law)::

        {joints: bed, courses: [1], sigma_I_e_Pa: 1.5e4, G_fI_J_m2: 0.27,
         sigma_II_e_Pa: 8.1e4, G_fII_J_m2: 18.54}
    """

    #: Fields left out of the case written back when null (the case's value).
    OMIT_NULL: ClassVar[tuple[str, ...]] = REGION_FIELDS

    joints: Literal["bed", "head"] = Field(
        description="bed: the bed joints on top of the courses; head: the head joints in them"
    )
    courses: list[Annotated[Whole, Field(ge=-200, le=200)]] | None = Field(
        None, min_length=1, max_length=200,
        description="courses (index: from 1 at the bottom, -1: the top); null: every course",
    )
    K_I_spring_Pa_m: Real | None = Field(None, description="as joint.K_I_spring_Pa_m (Pa/m)")
    K_II_spring_Pa_m: Real | None = Field(None, description="as joint.K_II_spring_Pa_m (Pa/m)")
    d_spring: Real | None = Field(None, description="as joint.d_spring (dimensionless)")
    sigma_I_e_Pa: Real | None = Field(None, description="as joint.sigma_I_e_Pa (Pa)")
    K_I_coh_Pa_m: Real | None = Field(None, description="as joint.K_I_coh_Pa_m (Pa/m)")
    G_fI_J_m2: Real | None = Field(None, description="as joint.G_fI_J_m2 (J/m^2)")
    sigma_II_e_Pa: Real | None = Field(None, description="as joint.sigma_II_e_Pa (Pa)")
    K_II_coh_Pa_m: Real | None = Field(None, description="as joint.K_II_coh_Pa_m (Pa/m)")
    G_fII_J_m2: Real | None = Field(None, description="as joint.G_fII_J_m2 (J/m^2)")
    d_coh_initial: Real | None = Field(None, description="as joint.d_coh_initial (dimensionless)")
    mu: Real | None = Field(None, description="as joint.mu (dimensionless)")
    p: Real | None = Field(None, description="as joint.p (dimensionless)")
    eta: Real | None = Field(None, description="as joint.eta (dimensionless)")

    def values(self) -> dict[str, float]:
        """The fields this region sets: ``{name: value}``."""
        return {f: float(getattr(self, f)) for f in REGION_FIELDS if getattr(self, f) is not None}


class Joint(Section):
    """The joint law, per unit area of interface (docs/model.md section 2).

    ``law``:

    - ``fczm``: frictional cohesive zone in series with an elastic spring (the study). Spring
      ``T = (1 - d_spring) K^spring u_s``; cohesion with one integrity shared by both modes,
      initial integrity ``1 - d_coh_initial``, exponential softening to ``eta``; Coulomb
      friction in compression with ``mu_eff = mu (1 - beta b)^p``.
    - ``coulomb``: dry Signorini-Coulomb contact with friction ``mu``; no cohesion, no spring
      (the spring and cohesive parameters are then unused).
    - ``dry``: a dry joint, Signorini-Coulomb contact with friction ``mu`` in series with
      interface stiffnesses ``K_n_Pa_m``, ``K_t_Pa_m`` (the closure of rough dry joints), no
      cohesion: ``T_n = K_n <u_n>_-``, ``|T_t| <= mu |T_n|``. Only ``mu`` and the two
      stiffnesses are used.

    Stiffnesses in Pa/m (traction per opening), stresses in Pa, fracture energies in J/m^2.
    Mode I is normal opening, mode II tangential sliding. The softening slope
    ``phi = sigma_e / (G - sigma_e^2 / (2 K_coh))`` needs ``G_f > sigma_e^2 / (2 K_coh)`` in each
    mode; it is checked here for the pure modes and for mixed modes.
    """

    law: Literal["fczm", "coulomb", "dry"] = Field(
        "fczm",
        description=(
            "fczm: cohesive zone + friction + spring; coulomb: dry friction only (rigid contact); "
            "dry: dry friction in series with the interface stiffnesses K_n_Pa_m, K_t_Pa_m"
        ),
    )
    K_n_Pa_m: Real | None = Field(
        None, gt=0, le=1e16,
        description="dry law: normal stiffness of the joint's closure (Pa/m; needed with law dry)",
    )
    K_t_Pa_m: Real | None = Field(
        None, gt=0, le=1e16,
        description="dry law: tangential stiffness of the joint (Pa/m; needed with law dry)",
    )
    K_I_spring_Pa_m: Real = Field(
        4.3e11, ge=1e6, le=1e16, description="normal stiffness of the series spring (Pa/m)"
    )
    K_II_spring_Pa_m: Real = Field(
        1.8e11, ge=1e6, le=1e16, description="tangential stiffness of the series spring (Pa/m)"
    )
    d_spring: Real = Field(
        0.953, ge=0.0, lt=1.0, description="constant damage of the spring (dimensionless)"
    )
    sigma_I_e_Pa: Real = Field(
        0.05e6, ge=1.0, le=1e9, description="mode I elastic limit (tensile strength) (Pa)"
    )
    K_I_coh_Pa_m: Real = Field(
        1.21e11, ge=1e6, le=1e16, description="mode I cohesive stiffness (Pa/m)"
    )
    G_fI_J_m2: Real = Field(3.0, ge=1e-3, le=1e6, description="mode I fracture energy (J/m^2)")
    sigma_II_e_Pa: Real = Field(
        0.27e6, ge=1.0, le=1e9, description="mode II elastic limit (shear strength) (Pa)"
    )
    K_II_coh_Pa_m: Real = Field(
        2.8e11, ge=1e6, le=1e16, description="mode II cohesive stiffness (Pa/m)"
    )
    G_fII_J_m2: Real = Field(206.0, ge=1e-3, le=1e6, description="mode II fracture energy (J/m^2)")
    d_coh_initial: Real = Field(
        0.99944,
        ge=0.0,
        lt=1.0,
        description="initial cohesive damage, b = 1 - d_coh_initial (dimensionless)",
    )
    mu: Real = Field(0.7, ge=0.0, le=2.0, description="friction coefficient (dimensionless)")
    p: Real = Field(
        1.0,
        gt=0.0,
        le=100.0,
        description="friction growth exponent in mu (1 - beta b)^p (dimensionless)",
    )
    eta: Real = Field(
        1e-4,
        ge=1e-12,
        lt=0.5,
        description="residual integrity at which the joint is fully broken (dimensionless)",
    )
    compression_spring: Literal["damaged", "undamaged"] = Field(
        "damaged",
        description="normal spring in compression: damaged (the study) or undamaged (LMGC90)",
    )
    scatter: JointScatter | None = Field(
        None, description="lognormal scatter of the joint strengths and energies (null: none)"
    )
    regions: list[JointRegion] = Field(
        default_factory=list, max_length=100,
        description="wall joints with properties of their own (the last region naming a "
        "joint wins; the scatter draws around each region's values)",
    )

    def with_values(self, values: dict[str, float]) -> Joint:
        """This joint with ``values`` in place of its own, no regions (validated: ValueError
        naming the first field the law refuses)."""
        data = {**self.model_dump(), **values, "regions": []}
        return type(self).model_validate(data)

    @model_validator(mode="after")
    def _check_dry(self) -> Joint:
        if self.law == "dry":
            raise_problems([(f, "the dry law needs it (Pa/m, > 0)") for f in ("K_n_Pa_m", "K_t_Pa_m")
                       if getattr(self, f) is None])
        if self.law != "fczm" and self.scatter is not None:
            raise_problems([("scatter", (f"the {self.law} law has no cohesion to scatter: "
                                    "remove joint.scatter or use law fczm"))])
        if self.law != "fczm" and self.regions:
            raise_problems([("regions", (f"given with law {self.law}; the regions set numbers of "
                                    "the fczm law: remove joint.regions or use law fczm"))])
        return self

    @model_validator(mode="after")
    def _check_regions(self) -> Joint:
        problems: list[tuple[str, str]] = []
        for i, region in enumerate(self.regions):
            values = region.values()
            if not values:
                problems.append((f"regions[{i}]", (
                    "sets no field; give one or more of " + ", ".join(REGION_FIELDS))))
                continue
            try:
                self.with_values(values)
            except ValidationError as exc:
                for message in messages(exc, Joint, ("joint",)):  # "joint.<field>: <text>"
                    where, _, text = message.partition(": ")
                    field = where.removeprefix("joint").lstrip(".")
                    problems.append((f"regions[{i}]" + (f".{field}" if field else ""), text))
        raise_problems(problems)
        return self

    @model_validator(mode="after")
    def _check_fracture_energies(self) -> Joint:
        if self.law != "fczm":
            return self
        problems: list[tuple[str, str]] = []
        modes = (
            ("G_fI_J_m2", self.G_fI_J_m2, "sigma_I_e_Pa", self.sigma_I_e_Pa,
             "K_I_coh_Pa_m", self.K_I_coh_Pa_m),
            ("G_fII_J_m2", self.G_fII_J_m2, "sigma_II_e_Pa", self.sigma_II_e_Pa,
             "K_II_coh_Pa_m", self.K_II_coh_Pa_m),
        )  # fmt: skip
        for g_name, g, s_name, s, k_name, k in modes:
            elastic = s * s / (2.0 * k)
            if not g > elastic:
                problems.append(
                    (
                        g_name,
                        (
                            f"got {g:.6g} J/m^2; it must exceed the elastic energy "
                            f"{s_name}^2 / (2 {k_name}) = {elastic:.6g} J/m^2, else the softening "
                            f"slope is undefined (raise {g_name} or {k_name}, or lower {s_name})"
                        ),
                    )
                )
        if not problems:
            m_bad = self._worst_mixed_mode()
            if m_bad is not None:
                problems.append(
                    (
                        "G_fII_J_m2",
                        (
                            f"with G_fI_J_m2 = {self.G_fI_J_m2:.6g} and G_fII_J_m2 = "
                            f"{self.G_fII_J_m2:.6g} J/m^2 the mixed-mode fracture energy is below "
                            f"the mixed-mode elastic energy at mode mixity m = {m_bad:.3g} (the "
                            "softening slope is undefined there): raise G_fI_J_m2 or G_fII_J_m2"
                        ),
                    )
                )
        raise_problems(problems)
        return self

    def _worst_mixed_mode(self) -> float | None:
        """Mode mixity m where G(m) <= sigma_e(m) delta_e(m) / 2, or None if there is none."""
        d1 = self.sigma_I_e_Pa / self.K_I_coh_Pa_m
        d2 = self.sigma_II_e_Pa / self.K_II_coh_Pa_m
        k1, k2 = self.K_I_coh_Pa_m, self.K_II_coh_Pa_m
        for i in range(-120, 121):
            m = 10.0 ** (i / 10.0)
            w1, w2 = d2 * d2, m * d1 * d1
            g = (w1 * self.G_fI_J_m2 + w2 * self.G_fII_J_m2) / (w1 + w2)
            delta_e_sq = d1 * d1 * d2 * d2 * (1.0 + m) / (w1 + w2)
            k = math.sqrt((k1 * k1 + m * k2 * k2) / (1.0 + m))
            if not g > 0.5 * k * delta_e_sq:
                return m
        return None
