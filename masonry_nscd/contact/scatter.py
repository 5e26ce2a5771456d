r"""The parameter rows of the joint points: the case's joint, its regions, and their scatter.

``joint.regions`` give some joints of a wall values of their own: each region is a row of the
parameter table, and the points of its joints take that row (the builder says which points a
region holds). Scatter then draws around each point's values, the region's or the case's.

The study explains its crack patterns by the scatter of the block-mortar interfaces. With
``joint.scatter`` each of its ``fields`` (``sigma_I_e_Pa``, ``sigma_II_e_Pa``, ``G_fI_J_m2``,
``G_fII_J_m2``) is drawn, independently, from the lognormal law of mean ``m`` (the case's value,
or the region's) and coefficient of variation ``cv``::

    ln X ~ N(mu, s^2),   s^2 = ln(1 + cv^2),   mu = ln m - s^2 / 2        (E[X] = m)

once per key: per joint, the pair of bodies it joins; per face, the element face of the
candidate that carries the point. Keys are numbered in the order of the points, so that a case
and a seed always give the same draws (regions or not). The table: row 0 the case's values (the
glue, and the points of the other groups), rows 1 to R the regions' in their order, then one row
per key with its draws (``contact.laws.params_from_case`` of the joint section with the drawn
values), which every point of the key takes. A draw the law refuses (the checks of
``case.Joint``: a fracture energy below the elastic energy of its mode, pure or mixed) raises
ValueError naming it.
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


def scatter_rows(joint, points: Sequence, scattered: np.ndarray,
                 region_of: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray,
                                                               dict[str, np.ndarray]]:
    """The parameter table, the row of each point, and the value of each field scattered or
    set by a region at each point (the case's value elsewhere; empty without either), for
    ``joint.scatter`` and ``joint.regions``.

    ``scattered``: (npt,) bool, the points that take scattered rows (the joint points).
    ``region_of``: (npt,) int, the index in ``joint.regions`` of each point's region (-1: none;
    None: no point in a region).
    """
    sc = joint.scatter
    npt = len(points)
    mean_of = np.zeros(npt, dtype=np.int64) if region_of is None else np.asarray(region_of) + 1
    means = [joint] + [joint.with_values(r.values()) for r in joint.regions]  # row = index
    rows = [laws.params_from_case(m) for m in means]
    key_of = np.full(npt, -1, dtype=np.int64)
    keys: dict[tuple, int] = {}
    if sc is not None:
        for a, p in enumerate(points):
            if scattered[a]:
                key = tuple(sorted(p.bodies)) if sc.per == "joint" else (p.bodies[0], p.face)
                key_of[a] = keys.setdefault((int(mean_of[a]), *key), len(keys))
        factors = lognormal_factors(sc.cv, (len(keys), len(sc.fields)),
                                    np.random.default_rng(sc.seed))
        for (m, *_), k in keys.items():
            mean = means[m]
            drawn = {f: float(getattr(mean, f)) * factors[k, i] for i, f in enumerate(sc.fields)}
            try:  # the schema's own checks of the joint (fracture energies, pure and mixed modes)
                drawn_joint = mean.with_values(drawn)
            except ValidationError as exc:
                values = ", ".join(f"{f} = {v:.4g}" for f, v in drawn.items())
                raise ValueError(f"joint.scatter: a draw ({values}) is one the law refuses: "
                                 f"{exc.errors()[0]['msg']}; lower joint.scatter.cv") from None
            rows.append(laws.params_from_case(drawn_joint))
    row_of = np.where(key_of >= 0, len(means) + key_of, mean_of)
    fields = list(sc.fields) if sc is not None else []
    fields += [f for r in joint.regions for f in r.values() if f not in fields]
    values = {}
    for f in fields:
        v = np.array([float(getattr(m, f)) for m in means])[mean_of]
        if sc is not None and f in sc.fields:
            scale = np.concatenate([factors[:, sc.fields.index(f)], [1.0]])
            v = v * scale[key_of]  # key -1: the last entry, 1
        values[f] = v
    return np.array(rows), row_of, values
