"""Geometric safety by limit analysis: the value of a case parameter (an arch's thickness, any
scale of a builder's geometry) at which the dead loads can just be carried, by bisection on
the feasibility of the static programme (:func:`masonry_nscd.limit.analysis.stands`).

Between a value ``a`` where the structure stands and one ``b`` where it does not (in either
order), each step builds the scene at the middle and keeps the half whose ends disagree, until
the bracket is narrower than ``rtol`` times its middle. The growing load is at zero: the case's
self-weight and other dead loads only. Each step is one scene and one programme (tens of
milliseconds for an arch), against one NSCD run per step of ``masonry threshold``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from masonry_nscd.limit import friction
from masonry_nscd.limit.analysis import stands


class BracketError(ValueError):
    """The two bounds do not bracket the threshold (both stand or both fall)."""


def threshold(load: Callable[[float], Any], bounds: tuple[float, float], *, rtol: float = 1e-5,
              max_steps: int = 60, facets: int = friction.DEFAULT_FACETS,
              tension: bool = False, solver: str = "clarabel") -> dict[str, Any]:
    """The threshold of the module docstring; ``load(value)`` is the case at ``value``.
    Returns ``value`` (the middle of the last bracket), ``standing`` and ``falling`` (its
    ends), ``uncertainty`` (half its width), ``steps`` (one per case solved, each ``value``
    and ``stands``) and ``time_s``."""
    t0 = time.perf_counter()
    steps = []

    def ok(v: float) -> bool:
        s = stands(load(v), facets=facets, tension=tension, solver=solver)
        steps.append({"value": v, "stands": s})
        return s

    a, b = (float(v) for v in bounds)
    sa, sb = ok(a), ok(b)
    if sa == sb:
        raise BracketError(f"both bounds {a:g} and {b:g} {'stand' if sa else 'fall'}: "
                           "the threshold is not between them")
    standing, falling = (a, b) if sa else (b, a)
    while abs(standing - falling) > rtol * abs(0.5 * (standing + falling)) \
            and len(steps) < max_steps:
        mid = 0.5 * (standing + falling)
        if ok(mid):
            standing = mid
        else:
            falling = mid
    return {"value": 0.5 * (standing + falling), "standing": standing, "falling": falling,
            "uncertainty": 0.5 * abs(standing - falling), "steps": steps,
            "time_s": time.perf_counter() - t0}
