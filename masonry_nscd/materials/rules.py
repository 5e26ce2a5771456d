"""Parameter rules: from a tested wall's material tests to the model's joint and unit parameters.

Pure functions on plain numbers (inputs in the units of the test tables: MPa, mm; outputs in
SI, as a case file takes them). The same rules for every wall: nothing here is fitted to a
wall's own force-displacement curve. docs/campaign.md lists the rules with their sources.

Joint (the project's ``fczm`` law, docs/model.md section 2):

- normal stiffness of the mortar layer, ``K_n = E_mortar / j`` (j the joint's thickness),
  where the mortar's modulus is measured: Lourenco's interface stiffness (Lourenco 1996;
  Lourenco and Rots 1997) for units that are not expanded by the joint; else from the
  series-spring relation of a prism of one unit of height h and one joint,
  ``(h + j)/E_m = h/E_u + 1/K_n``, E_m the masonry's modulus from its compression test. The
  whole joint flexibility is the spring's (``d_spring = 0``);
- shear stiffness ``K_t = K_n / (2 (1 + nu))``: the ratio G/E of an isotropic joint layer;
- cohesive stiffnesses ten times the spring's, so that an uncracked joint is as stiff as its
  spring within 10 %;
- cohesion (mean initial shear strength) from the mortar's class by the characteristic
  initial shear strength f_vk0 of Eurocode 6 (EN 1996-1-1, table 3.4, natural stone units,
  general purpose mortar) divided by 0.8 (EN 1052-3: characteristic = 0.8 mean). The M2.5-M9
  row (0.15 MPa) is confirmed by a public quotation of the table; the M1-M2 (0.10) and
  M10-M20 (0.20) rows and the 0.8 are recalled, not confirmed against the standards. Where
  the mortar's strength was not measured, the weakest class's (M1-M2), that of historic lime
  mortars;
- tensile bond and fracture energies as ratios of the interface parameters Lourenco and Rots
  (1997) used for the TU Eindhoven shear walls: f_t 0.25 MPa, c 0.35 MPa, G_fI 0.018 N/mm,
  G_fII 0.125 N/mm, so ``f_t = c / 1.4``, ``G_fI = 0.072 f_t`` and ``G_fII = 0.357 c`` (f_t, c
  in MPa, G in N/mm). Read from a public re-implementation that quotes that parameter set,
  not from the paper itself. Not used: ``G_fI = 0.029 f_t`` and ``G_fII = 0.125 c``, which
  could not be confirmed (0.125 is that set's G_fII in N/mm, not a ratio to c);
- friction coefficient 0.7, the project's default: Lourenco and Rots's set has 0.75 (clay
  brick); the range 0.63-0.74 for granite joints attributed to Vasconcelos and Lourenco
  (2009) is not confirmed;
- a virgin joint (``d_coh_initial = 0``): the joint's own strengths are the mortar's.

Dry joint (the project's ``dry`` law: Coulomb friction in series with the joint's closure
stiffnesses, no cohesion, no tension), where the test table names the joints dry:

- normal stiffness from the prism's series springs with no joint thickness,
  ``h/E_m = h/E_u + 1/K_n``: the masonry's extra compliance over its units' is the closure of
  its dry joints;
- shear stiffness ``K_t = K_n / (2 (1 + nu))``, as for mortared joints;
- friction coefficient 0.65, the project's dry stone wall's (dressed sandstone on sandstone);
  direct shear tests on dry joints of dressed granite (Vasconcelos and Lourenco 2009) gave
  friction coefficients of the same order, 0.6 to 0.7 (recalled, not confirmed).

Units (ENDO3D, docs/model.md section 3): ``E`` the units' tested modulus; ``R_c`` the
masonry's compressive strength from its compression test, where measured, else the units' own.
The joints cannot crush (the fczm law has no cap in compression), while tested masonry crushes
at its prisms' strength, well below its units' (2 to 19 times in the walls of
docs/campaign.md; the mortar, squeezed between the units, splits them): in a simplified
micro-model that crushing is the interface's cap at the masonry's strength (Lourenco, Rots and
Blaauwendraad 1995; Lourenco and Rots 1997); here it is the units'. ``R_t = 0.1 R_c`` (the
order of the tensile over the compressive strength of rocks, e.g. granite 7-25 against
100-250 MPa; no source for these stones, not confirmed); tensile peak strain ``R_t / E``;
tensile fracture energy of fib Model Code 2010, eq. (5.1-9), ``G_F = 73 f_cm^0.18`` N/m with
that R_c (a rule for concrete, borrowed; confirmed); compressive peak strain ``2 R_c / E``
(the secant modulus at the peak half the initial one, the rules' choice); the rest as the
project's study wall.
"""

from __future__ import annotations

#: Poisson's ratio of the joint layer and of the units (isotropic assumption).
NU = 0.2
#: Cohesive stiffness over spring stiffness (dimensionless).
COHESIVE_OVER_SPRING = 10.0
#: Characteristic over mean value of a strength (EN 1052-3).
CHARACTERISTIC_OVER_MEAN = 0.8
#: The interface parameters of Lourenco and Rots (1997) for the TU Eindhoven shear walls:
#: tensile bond and cohesion (MPa), mode I and mode II fracture energies (N/mm).
LR_TENSILE_BOND_MPA = 0.25
LR_COHESION_MPA = 0.35
LR_G_FI_N_MM = 0.018
LR_G_FII_N_MM = 0.125
#: Cohesion over tensile bond strength: 0.35 / 0.25 = 1.4.
COHESION_OVER_TENSION = LR_COHESION_MPA / LR_TENSILE_BOND_MPA
#: Friction coefficient: the project's default (Lourenco and Rots's set: 0.75).
FRICTION = 0.7
#: Friction coefficient of dry joints of dressed stone (the project's dry stone wall).
DRY_FRICTION = 0.65
#: Mode I and mode II fracture energies per unit strength (mm = kJ/m^2 per MPa):
#: 0.018 / 0.25 = 0.072 and 0.125 / 0.35 = 0.357.
G_FI_PER_FT_MM = LR_G_FI_N_MM / LR_TENSILE_BOND_MPA
G_FII_PER_C_MM = LR_G_FII_N_MM / LR_COHESION_MPA
#: Units' tensile over compressive strength (order of magnitude of rocks; not confirmed).
TENSION_OVER_COMPRESSION = 0.1
#: Units' compressive peak strain over R_c / E.
PEAK_STRAIN_FACTOR = 2.0
#: Unit weight assumed by the test tables for the self-weight (N/m^3).
UNIT_WEIGHT_N_M3 = 20e3
GRAVITY_M_S2 = 9.81


def joint_normal_stiffness(E_masonry_MPa: float, E_unit_MPa: float, unit_height_mm: float,
                           joint_mm: float = 0.0) -> float:
    """Normal stiffness of a bed joint (Pa/m) from the masonry's modulus: a prism of one unit
    of height h and one joint of thickness j in series, ``(h + j) / E_m = h / E_u + 1 / K_n``.

    E_m the masonry's modulus (its compression test), E_u the units' (their own test); the
    model's units are h high with a gap of j between them, spanned by the joint's spring. With
    ``j = 0``, ``K_n = E_u E_m / (h (E_u - E_m))``. Raises ValueError when the prism is not
    more compliant than its units (no joint stiffness) or a value is not positive.
    """
    if min(E_masonry_MPa, E_unit_MPa, unit_height_mm) <= 0 or joint_mm < 0:
        raise ValueError("moduli and unit height must be positive, the joint not negative")
    h, j = unit_height_mm * 1e-3, joint_mm * 1e-3
    compliance = (h + j) / (E_masonry_MPa * 1e6) - h / (E_unit_MPa * 1e6)
    if compliance <= 0:
        raise ValueError(f"masonry modulus {E_masonry_MPa} MPa not below the units' "
                         f"{E_unit_MPa} MPa: the series-spring rule gives no joint stiffness")
    return 1.0 / compliance


def mortar_joint_normal_stiffness(E_mortar_MPa: float, joint_mm: float) -> float:
    """Normal stiffness of a bed joint (Pa/m) from the mortar's modulus: the mortar layer of
    thickness j alone, ``K_n = E_mortar / j``.

    Lourenco's interface stiffness of a simplified micro-model (Lourenco 1996; Lourenco and
    Rots 1997), ``k_n = E_u E_mo / (j (E_u - E_mo))``, is the same layer seen from units
    expanded by the joint's thickness; the model's units are not expanded (the joint is a gap
    of j between them), so its spring is the layer's own ``E_mo / j``.
    """
    if E_mortar_MPa <= 0 or joint_mm <= 0:
        raise ValueError("mortar modulus and joint thickness must be positive")
    return E_mortar_MPa * 1e6 / (joint_mm * 1e-3)


def joint_shear_stiffness(K_n_Pa_m: float, nu: float = NU) -> float:
    """Shear stiffness of a joint (Pa/m): ``K_t = K_n / (2 (1 + nu))``, the ratio G/E of an
    isotropic layer."""
    return K_n_Pa_m / (2.0 * (1.0 + nu))


def eurocode6_fvk0_MPa(mortar_fc_MPa: float | None) -> float:
    """Characteristic initial shear strength f_vk0 (MPa) of natural stone units with general
    purpose mortar by the mortar's strength class (EN 1996-1-1, table 3.4): M1-M2 (below
    2.5 MPa) 0.10; M2.5-M9 0.15 (confirmed by a public quotation); M10-M20 0.20 (the first and
    last rows recalled, not confirmed). Without the mortar's strength (None), the weakest
    class's 0.10: the lime mortars of historic masonry lie below 2.5 MPa."""
    if mortar_fc_MPa is None or mortar_fc_MPa < 2.5:
        return 0.10
    if mortar_fc_MPa < 10.0:
        return 0.15
    return 0.20


def joint_cohesion_MPa(mortar_fc_MPa: float | None) -> float:
    """Mean cohesion c (MPa): ``f_vk0 / 0.8`` (:func:`eurocode6_fvk0_MPa`; the 0.8 of
    EN 1052-3, recalled, not confirmed)."""
    return eurocode6_fvk0_MPa(mortar_fc_MPa) / CHARACTERISTIC_OVER_MEAN


def joint_tensile_bond_MPa(cohesion_MPa: float) -> float:
    """Tensile bond strength f_t (MPa) = c / 1.4 (Lourenco and Rots: 0.25 against 0.35 MPa)."""
    return cohesion_MPa / COHESION_OVER_TENSION


def fracture_energies_J_m2(ft_MPa: float, c_MPa: float) -> tuple[float, float]:
    """Mode I and II fracture energies (J/m^2) in the ratios of Lourenco and Rots's interface
    parameters: ``G_fI = (0.018 / 0.25) f_t``, ``G_fII = (0.125 / 0.35) c`` (f_t, c in MPa to
    G in N/mm; 1 N/mm = 1000 J/m^2)."""
    return G_FI_PER_FT_MM * ft_MPa * 1e3, G_FII_PER_C_MM * c_MPa * 1e3


def joint_parameters(E_masonry_MPa: float | None, E_unit_MPa: float, unit_height_mm: float,
                     mortar_fc_MPa: float | None, mortar_E_MPa: float | None = None,
                     joint_mm: float = 0.0) -> dict[str, float]:
    """The ``joint`` section (fczm law, SI) of the rules above: the normal stiffness the mortar
    layer's (:func:`mortar_joint_normal_stiffness`) where the mortar's modulus is measured,
    else the prism's (:func:`joint_normal_stiffness`)."""
    if mortar_E_MPa is not None and mortar_E_MPa > 0:
        K_n = mortar_joint_normal_stiffness(mortar_E_MPa, joint_mm)
    else:
        K_n = joint_normal_stiffness(E_masonry_MPa, E_unit_MPa, unit_height_mm, joint_mm)
    K_t = joint_shear_stiffness(K_n)
    c = joint_cohesion_MPa(mortar_fc_MPa)
    ft = joint_tensile_bond_MPa(c)
    G_I, G_II = fracture_energies_J_m2(ft, c)
    return {
        "law": "fczm", "K_I_spring_Pa_m": K_n, "K_II_spring_Pa_m": K_t, "d_spring": 0.0,
        "sigma_I_e_Pa": ft * 1e6, "K_I_coh_Pa_m": COHESIVE_OVER_SPRING * K_n, "G_fI_J_m2": G_I,
        "sigma_II_e_Pa": c * 1e6, "K_II_coh_Pa_m": COHESIVE_OVER_SPRING * K_t,
        "G_fII_J_m2": G_II, "d_coh_initial": 0.0, "mu": FRICTION, "p": 1.0,
    }


def dry_joint_parameters(E_masonry_MPa: float, E_unit_MPa: float,
                         unit_height_mm: float) -> dict[str, float | str]:
    """The ``joint`` section (dry law, SI) of a wall whose units touch: the closure stiffness
    of the prism (:func:`joint_normal_stiffness` with no joint thickness), its shear
    stiffness and the dry friction coefficient."""
    K_n = joint_normal_stiffness(E_masonry_MPa, E_unit_MPa, unit_height_mm, 0.0)
    return {"law": "dry", "K_n_Pa_m": K_n, "K_t_Pa_m": joint_shear_stiffness(K_n),
            "mu": DRY_FRICTION}


def tensile_fracture_energy_J_m2(fc_MPa: float) -> float:
    """Tensile fracture energy of the units (J/m^2): fib Model Code 2010, eq. (5.1-9),
    ``73 f_cm^0.18`` (f_cm the mean compressive strength in MPa)."""
    return 73.0 * fc_MPa ** 0.18


def unit_parameters(unit_fc_MPa: float | None, unit_E_MPa: float,
                    masonry_fc_MPa: float | None = None) -> dict[str, float]:
    """The ENDO3D numbers of the units (SI) from their modulus and a compressive strength
    f_c: the masonry's (its compression test) where given, else the units' own (module
    docstring: the joints cannot crush, so the masonry's crushing is the units');
    ``R_t``, ``G_ft`` and ``eps_pic_c`` follow from that f_c. Raises ValueError without
    either strength."""
    fc = masonry_fc_MPa if masonry_fc_MPa else unit_fc_MPa
    if not fc or fc <= 0:
        raise ValueError("a compressive strength (the masonry's or the units') is needed")
    E = unit_E_MPa * 1e6
    R_c = fc * 1e6
    R_t = TENSION_OVER_COMPRESSION * R_c
    return {
        "E_Pa": E, "nu": NU, "R_t_Pa": R_t, "eps_pic_t": R_t / E,
        "G_ft_J_m2": tensile_fracture_energy_J_m2(fc), "R_c_Pa": R_c,
        "eps_pic_c": PEAK_STRAIN_FACTOR * R_c / E,
    }


def density_kg_m3() -> float:
    """Density of the units (kg/m^3): the tables' unit weight of 20 kN/m^3."""
    return UNIT_WEIGHT_N_M3 / GRAVITY_M_S2
