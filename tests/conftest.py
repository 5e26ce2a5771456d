"""Helpers and fixtures shared by the test modules."""

from __future__ import annotations

import pytest


def interrupt_at(monkeypatch, step: int, exc: BaseException | None = None) -> None:
    """Make the integrator raise ``exc`` (KeyboardInterrupt by default) once, instead of
    making step ``step`` of the run (an interrupted run, Ctrl-C)."""
    from masonry_nscd.nscd.integrator import Integrator

    orig, fired = Integrator.step, []

    def step_once(self):
        if self.step_index + 1 == step and not fired:
            fired.append(True)
            raise exc or KeyboardInterrupt
        return orig(self)

    monkeypatch.setattr(Integrator, "step", step_once)


@pytest.fixture
def interrupt_before_step(monkeypatch):
    """``arm(step, exc=None)``: :func:`interrupt_at` with this test's monkeypatch."""
    return lambda step, exc=None: interrupt_at(monkeypatch, step, exc)
