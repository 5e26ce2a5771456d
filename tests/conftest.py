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


def wait_for_rows(proc, csv_path, rows: int, timeout_s: float = 120.0) -> None:
    """Wait until the run of subprocess ``proc`` has more than ``rows`` lines in ``csv_path``
    (or has ended, or ``timeout_s`` has passed): the moment to interrupt it."""
    import time

    deadline = time.time() + timeout_s
    while time.time() < deadline and proc.poll() is None:
        if csv_path.exists() and len(csv_path.read_text().splitlines()) > rows:
            return
        time.sleep(0.05)


def stop_by_sigterm(proc, timeout_s: float) -> None:
    """Send SIGTERM to the run of subprocess ``proc`` and check that it stopped as
    interrupted: exit code 130 and a message that says how to resume (a run that had already
    finished skips the test)."""
    import signal

    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=timeout_s)
    if proc.returncode == 0:  # pragma: no cover - the machine was faster than the polling
        pytest.skip("the run finished before SIGTERM")
    assert proc.returncode == 130, err
    assert "--resume" in err
