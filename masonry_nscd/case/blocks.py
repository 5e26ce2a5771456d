"""The material of the units: elastic, ENDO3D (its parameters) or rigid."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import SQRT3, Real, Section


class Endo3d(Section):
    """Parameters of the ENDO3D damage-plasticity law of the stone (docs/model.md section 3).

    Strengths in Pa, strains dimensionless, fracture energies in J/m^2. ``eps_pic_t`` is the
    study's peak tensile strain; the law of model.md reaches its tensile peak at ``R_t / E``
    (9.009e-5 with the defaults, the same number), so the value is kept for the record.
    """

    R_t_Pa: Real = Field(
        1.0e6, ge=1e3, le=1e9, description="tensile strength R_t (Pa), Rankine criterion"
    )
    eps_pic_t: Real = Field(
        0.9009e-4, gt=0.0, lt=1.0, description="strain at the tensile peak (dimensionless)"
    )
    G_ft_J_m2: Real = Field(
        60.0, ge=1e-3, le=1e6, description="tensile fracture energy G_ft (J/m^2), Hillerborg"
    )
    R_c_Pa: Real = Field(9.46e6, ge=1e3, le=1e10, description="compressive strength R_c (Pa)")
    eps_pic_c: Real = Field(
        0.13e-1, gt=0.0, lt=1.0, description="strain at the compressive peak (dimensionless)"
    )
    delta: Real = Field(
        0.4,
        ge=0.0,
        lt=SQRT3,
        description="Drucker-Prager confinement coefficient (dimensionless, < sqrt 3)",
    )
    beta: Real = Field(
        0.2,
        ge=0.0,
        lt=SQRT3,
        description="Drucker-Prager dilatancy coefficient (dimensionless, 0 <= beta <= delta)",
    )
    eps_kdc: Real = Field(
        0.18e-1,
        gt=0.0,
        lt=1.0,
        description="post-peak compressive damage strain scale (dimensionless)",
    )
    crushing_length_m: Real = Field(
        0.0, ge=0.0, le=10.0,
        description="length of an element whose post-peak strain scale is eps_kdc (m; 0: the "
        "law as specified, eps_kdc a strain whatever the mesh; > 0: regularised by the element "
        "size)",
    )
    DCPK: Real = Field(
        1.0, ge=0.0, le=1.0, description="cap on the pre-peak compressive damage (dimensionless)"
    )
    REF_Pa: Real = Field(0.3e6, ge=1e2, le=1e9, description="crack reclosure stress REF (Pa)")
    GFR_J_m2: Real = Field(4.5, ge=1e-3, le=1e6, description="crack reclosure energy GFR (J/m^2)")
    relaxation_time_s: Real = Field(
        1e-3, ge=0.0, le=1.0,
        description="Duvaut-Lions relaxation time tau of the viscous regularisation (s); "
        "0 = the rate-independent law (materials/blocks.py)",
    )

    @model_validator(mode="after")
    def _check_strengths(self) -> Endo3d:
        """``R_t < R_c``; ``beta <= delta``: the Drucker-Prager flow dissipates
        ``dlambda (C + (delta - beta) p)`` (J/m^3), negative at pressures
        ``p > C/(beta - delta)`` when ``beta > delta``: the law then creates energy (a shear
        cycle with beta = 1.5, delta = 0 ratchets the effective pressure up to 100 R_c). ``materials.endo3d.endo3d_params`` only warns, for studies of the kernel."""
        problems: list[tuple[str, str]] = []
        if not self.beta <= self.delta:
            problems.append(
                (
                    "beta",
                    (
                        f"got {self.beta:.6g}; allowed: 0 <= beta <= delta = {self.delta:.6g} "
                        "(with beta > delta the Drucker-Prager flow dissipates a negative "
                        "energy dlambda (C + (delta - beta) p) at pressures p > C/(beta - delta))"
                    ),
                )
            )
        if not self.R_t_Pa < self.R_c_Pa:
            problems.append(
                (
                    "R_t_Pa",
                    (
                        f"got {self.R_t_Pa:.9g} Pa; the tensile strength must be lower than the "
                        f"compressive strength R_c_Pa = {self.R_c_Pa:.9g} Pa"
                    ),
                )
            )
        raise_problems(problems)
        return self


class Blocks(Section):
    """The units (blocks): material model, density, elasticity.

    ``material``: ``endo3d`` (damage-plasticity, the study), ``elastic`` (linear elastic, the
    study's counter-example, same E and nu) or ``rigid`` (rigid bodies, for fast studies where
    block deformation does not matter; E and nu unused). The ``endo3d`` section is used only
    with ``material: endo3d``.
    """

    material: Literal["elastic", "endo3d", "rigid"] = Field(
        "endo3d", description="block material model: elastic, endo3d or rigid"
    )
    density_kg_m3: Real = Field(2000.0, ge=100.0, le=1e5, description="density (kg/m^3)")
    E_Pa: Real = Field(11.1e9, ge=1e6, le=1e13, description="Young's modulus E (Pa)")
    nu: Real = Field(
        0.2, gt=-1.0, lt=0.5, description="Poisson's ratio (dimensionless, -1 < nu < 0.5)"
    )
    endo3d: Endo3d = Field(
        default_factory=Endo3d, description="ENDO3D parameters (used when material is endo3d)"
    )

    @model_validator(mode="after")
    def _check_endo3d_with_E(self) -> Blocks:
        """For ENDO3D blocks, the checks of ``materials.endo3d.endo3d_params`` that involve E:
        ``R_t < R_c,eff`` and ``R_t delta <= R_c,eff (1/sqrt3 - delta/3)``, with the effective
        compressive strength ``R_c,eff`` of that function (kept equal to it by
        tests/test_case.py; not imported here, it would load numba)."""
        if self.material != "endo3d":
            return self
        e, E = self.endo3d, self.E_Pa
        if e.DCPK > 0.0 and e.eps_pic_c > e.R_c_Pa / E:
            cap_free = e.DCPK >= 1.0 - e.R_c_Pa / (E * e.eps_pic_c)
            rc_eff = E * e.eps_pic_c if cap_free else e.R_c_Pa / (1.0 - e.DCPK)
        else:
            rc_eff = e.R_c_Pa
        problems: list[tuple[str, str]] = []
        if not e.R_t_Pa < rc_eff:
            problems.append(("endo3d.R_t_Pa", (
                f"got {e.R_t_Pa:.6g} Pa; it must be lower than the effective compressive "
                f"strength R_c,eff = {rc_eff:.6g} Pa (from R_c_Pa, eps_pic_c, DCPK and E_Pa)")))
        elif not e.R_t_Pa * e.delta <= rc_eff * (1.0 / SQRT3 - e.delta / 3.0):
            problems.append(("endo3d.delta", (
                f"got {e.delta:.6g}; the initial cohesion R_t delta = {e.R_t_Pa * e.delta:.6g} "
                f"Pa exceeds the peak cohesion R_c,eff (1/sqrt3 - delta/3) = "
                f"{rc_eff * (1.0 / SQRT3 - e.delta / 3.0):.6g} Pa: lower delta or R_t_Pa")))
        raise_problems(problems)
        return self
