"""Adaptive step size of the time loop: steps of ``h 2^k``, grown while they stay easy.

The loading of the study's walls is quasi-static: over most of a run (the elastic branch, the
residual plateau) the Newton solve of a step of ``h`` converges in a few iterations, and a step
of ``2 h`` carries the same state change at the cost of one step (measurements:
docs/choices.md, docs/performance.md). The control below lets
the step grow by doublings, ``h_k = h 2^k`` with ``0 <= k <= max_level``, and falls back when a
step is hard:

* a step is *easy* when it converged (tolerance met, no failed material point) within
  ``easy_iterations`` Newton iterations, was not subdivided, and no joint lost more than
  ``easy_damage`` of its integrity and no ENDO3D Gauss point gained more than ``easy_damage``
  of damage in it (a softening path is followed in steps that resolve it: a joint breaking
  earlier or later moves the rest of the curve);
* after ``grow_after`` easy steps in a row, the level rises by one (the step doubles);
* a step that converged but needed more than ``2 easy_iterations`` iterations, or in which a
  damage grew by more than ``2 easy_damage``, lowers the level by one for the next step (a
  joint opening, a crack forming: the path is bending);
* a step of level ``k > 0`` that does not converge (or diverges) is discarded and made again
  from its start at level ``k - 1``, down to level 0, where the halving of the integrator
  (``Integrator.max_halvings``) takes over.

Steps stay on the grid of ``h``: a step of level ``k`` starts at a multiple of ``h 2^k`` (``n``,
the number of steps of ``h`` from ``t = 0``, is a multiple of ``2^k``), so that a step never
crosses a multiple of ``h 2^max_level``; outputs every ``m`` steps of ``h`` with ``m`` a multiple
of ``2^max_level`` therefore fall on the end of a step. A step also never ends after a given
limit (the next change of the supports, the end of the loading, the start of a turn of a cyclic
or tabulated path, through which the steps are of ``h``: ``Scene.step_limit_s``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class StepSizeControl:
    """The level ``k`` of the next step (its size ``h 2^k``) and the memory of the last steps."""

    max_level: int  # the largest step is h 2^max_level
    grow_after: int = 2  # easy steps in a row before the level rises (count)
    easy_iterations: int = 4  # an easy step converged within this many iterations (count)
    easy_damage: float = math.inf  # ... and no damage grew by more than this (dimensionless)
    level: int = 0  # the level the next step tries (before alignment)
    easy: int = 0  # easy steps in a row at the current level

    def __post_init__(self):
        if self.max_level < 0:
            raise ValueError(f"max_level must be >= 0, got {self.max_level}")
        if self.grow_after < 1 or self.easy_iterations < 1:
            raise ValueError("grow_after and easy_iterations must be >= 1, got "
                             f"{self.grow_after} and {self.easy_iterations}")

    def level_for(self, n: int, limit: float) -> int:
        """Level of a step that starts after ``n`` steps of ``h`` (``t = n h``): at most
        ``level``, aligned (``n`` a multiple of ``2^k``), and ending at or before ``limit``
        steps of ``h``."""
        k = self.level
        while k > 0 and (n % (1 << k) or n + (1 << k) > limit):
            k -= 1
        return k

    def failed(self, k: int) -> int:
        """A step of level ``k > 0`` did not converge: the level to make it again at."""
        self.level = min(self.level, k - 1)
        self.easy = 0
        return k - 1

    def accepted(self, k: int, iterations: int, easy: bool, damage: float = 0.0) -> None:
        """A step of level ``k`` was kept, after ``iterations`` Newton iterations, the largest
        damage growth ``damage`` in it; ``easy``: it converged at once (not subdivided, no
        material failure)."""
        if easy and iterations <= self.easy_iterations and damage <= self.easy_damage:
            self.easy += 1
            if self.easy >= self.grow_after and self.level < self.max_level:
                self.level += 1
                self.easy = 0
        else:
            self.easy = 0
            if not easy or iterations > 2 * self.easy_iterations \
                    or damage > 2 * self.easy_damage:
                self.level = max(0, min(self.level, k) - 1)

    def memory(self) -> tuple[int, int]:
        """``(level, easy)``, what a checkpoint keeps so that a resumed run steps the same."""
        return self.level, self.easy
