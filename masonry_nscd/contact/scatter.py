r"""Scattered joint properties: a parameter row per joint (or per element face of a joint).

The study explains its crack patterns by the scatter of the block-mortar interfaces. With
``joint.scatter`` each of its ``fields`` (``sigma_I_e_Pa``, ``sigma_II_e_Pa``, ``G_fI_J_m2``,
``G_fII_J_m2``) is drawn, independently, from the lognormal law of mean ``m`` (the case's value)
and coefficient of variation ``cv``::

    ln X ~ N(mu, s^2),   s^2 = ln(1 + cv^2),   mu = ln m - s^2 / 2        (E[X] = m)

once per key: per joint, the pair of bodies it joins; per face, the element face of the
candidate that carries the point. Keys are numbered in the order of the points, so that a case
and a seed always give the same draws. Each draw becomes a row of the parameter table
(``contact.laws.params_from_case`` of the case's joint section with the drawn values), and
every point of the key takes that row; row 0 keeps the case's values (the glue, and the points
of the other groups). A draw the law refuses (the checks of ``case.Joint``: a fracture energy
below the elastic energy of its mode, pure or mixed) raises ValueError naming it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from pydantic import ValidationError

from masonry_nscd.contact import laws


def lognormal_factors(cv: float, size: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
    """Draws of ``X / m`` for a lognormal ``X`` of mean ``m`` and coefficient of variation
    ``cv`` (module docstring)."""
    s2 = math.log1p(cv * cv)
    return np.exp(rng.normal(-0.5 * s2, math.sqrt(s2), size=size))


def scatter_rows(joint, points: Sequence, scattered: np.ndarray) -> tuple[np.ndarray,
                                                                          np.ndarray,
                                                                          dict[str, np.ndarray]]:
    """The parameter table, the row of each point, and the drawn value of each field at each
    point (the case's value where it is not scattered), for ``joint.scatter``.

    ``scattered``: (npt,) bool, the points that take scattered rows (the joint points).
    """
    sc = joint.scatter
    base = laws.params_from_case(joint)
    if sc is None:
        return base[None, :], np.zeros(len(points), dtype=np.int64), {}
    keys: dict[tuple, int] = {}
    row_of = np.zeros(len(points), dtype=np.int64)
    for a, p in enumerate(points):
        if not scattered[a]:
            continue
        key = tuple(sorted(p.bodies)) if sc.per == "joint" else (p.bodies[0], p.face)
        row_of[a] = keys.setdefault(key, len(keys) + 1)
    rng = np.random.default_rng(sc.seed)
    factors = lognormal_factors(sc.cv, (len(keys), len(sc.fields)), rng)
    rows = [base]
    case_values = joint.model_dump()
    for k in range(len(keys)):
        drawn = {f: float(getattr(joint, f)) * factors[k, i] for i, f in enumerate(sc.fields)}
        try:  # the schema's own checks of the joint (fracture energies, pure and mixed modes)
            drawn_joint = type(joint).model_validate({**case_values, **drawn})
        except ValidationError as exc:
            values = ", ".join(f"{f} = {v:.4g}" for f, v in drawn.items())
            raise ValueError(f"joint.scatter: a draw ({values}) is one the law refuses: "
                             f"{exc.errors()[0]['msg']}; lower joint.scatter.cv") from None
        rows.append(laws.params_from_case(drawn_joint))
    values = {}
    for i, f in enumerate(sc.fields):
        scale = np.concatenate([[1.0], factors[:, i]])
        values[f] = float(getattr(joint, f)) * scale[row_of]
    return np.array(rows), row_of, values
