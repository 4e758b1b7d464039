"""The integrator kit catches a stage evaluated at the wrong time (on the driven block
x'' = -sin t, exact solution x = sin t) and a method that ignores rtol; the "failure" and
"metadata" checks catch a NotImplementedError stub and a TODO summary."""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest

from workbench.plugin.integrator import Integrator, step_for_tolerance
from workbench.plugin.registry import REGISTRY, PluginInfo
from workbench.testing import check_integrator
from workbench.testing.integrator import TIME_DEPENDENCE_RATIO

GYRO = ["torque-free-symmetric-gyro"]


@pytest.fixture
def register(monkeypatch: pytest.MonkeyPatch) -> Any:
    """Register plugin classes in the global registry for one test."""
    REGISTRY.discover()

    def add(plugin: type) -> type:
        info = PluginInfo("integrator", plugin.name, plugin, plugin.__module__)
        monkeypatch.setitem(REGISTRY.entries["integrator"], plugin.name, info)
        return plugin

    return add


class Midpoint(Integrator):
    """Explicit midpoint rule (Runge's order-2 method), its step from rtol (test)."""

    name = "test-midpoint"
    summary = "explicit midpoint, order 2, step from rtol (test)"
    accepts = {"ode": 0}  # noqa: RUF012

    order = 2

    def stage_time(self, t: float, h: float) -> float:
        return t + h / 2

    def advance(self, rhs: Any, t: float, y: np.ndarray, h: float) -> np.ndarray:
        (k1,) = rhs(t, y)
        (k2,) = rhs(self.stage_time(t, h), y + h / 2 * k1)
        return y + h * k2

    def integrate(self, task: Any, trajectory: Any) -> None:
        rhs, y = task.form.rhs, task.y0.copy()
        step = step_for_tolerance(task.rtol, self.order)
        out, steps = [y.copy()], 0
        for t0, t1 in zip(task.times[:-1], task.times[1:], strict=True):
            n = max(1, int(np.ceil((t1 - t0) / step)))
            h = (t1 - t0) / n
            for k in range(n):
                y = self.advance(rhs, t0 + k * h, y, h)
            steps += n
            out.append(y.copy())
        trajectory.times, trajectory.y = task.times, np.array(out)
        trajectory.stats.n_steps = steps


class WrongStageTime(Midpoint):
    """The midpoint stage evaluated at t instead of t + h/2: right on autonomous
    problems, first order on non-autonomous ones (test)."""

    name = "test-wrong-stage-time"
    summary = "explicit midpoint with its stage at the wrong time (test)"

    def stage_time(self, t: float, h: float) -> float:
        return t


class ForwardEuler(Midpoint):
    """Explicit Euler, order 1, its step from rtol as the docs say (test): right, but
    above the kit's absolute bound on the driven block at rtol 1e-8."""

    name = "test-forward-euler"
    summary = "explicit Euler, order 1, step from rtol (test)"
    order = 1

    def advance(self, rhs: Any, t: float, y: np.ndarray, h: float) -> np.ndarray:
        return y + h * rhs(t, y)[0]


class IgnoresRtol(Midpoint):
    """The midpoint rule at 0.1 ms whatever rtol says: accurate, but deaf to rtol (test)."""

    name = "test-ignores-rtol"
    summary = "explicit midpoint at a fixed 0.1 ms step (test)"

    def integrate(self, task: Any, trajectory: Any) -> None:
        task.rtol = 1e-8  # the step rule then always gives 1e-4 s
        super().integrate(task, trajectory)


class Stub(Integrator):
    """TODO one paragraph: the method, its order, the reference."""

    name = "test-stub"
    summary = "TODO: one line shown by `workbench list integrators`"
    accepts = {"ode": 0}  # noqa: RUF012

    def integrate(self, task: Any, trajectory: Any) -> None:
        raise NotImplementedError("write the method")


def result(report: Any, check: str) -> Any:
    (found,) = [r for r in report.results if r.check == check]
    return found


def test_the_right_midpoint_passes_and_the_wrong_stage_time_is_caught(register: Any) -> None:
    register(Midpoint)
    register(WrongStageTime)
    right = check_integrator(Midpoint, GYRO)
    assert result(right, "time-dependence").status == "pass"
    assert result(right, "tolerance-response").status == "pass"
    wrong = check_integrator(WrongStageTime, GYRO)
    # on the autonomous gyro both are the same method: the gyro cannot tell them apart
    assert result(wrong, "accuracy").status == result(right, "accuracy").status
    caught = result(wrong, "time-dependence")
    assert caught.status == "fail"
    # first order: the force is sampled h/2 early, so x' is off by h/2 (sin 2) and x by
    # h/2 (1 - cos 2) at t = 2 s; h = 1e-4 s at rtol 1e-8
    h = step_for_tolerance(1e-8, 2)
    expected = h / 2 * (np.sin(2.0) + 1 - np.cos(2.0))
    measured = float(re.search(r"rtol 1e-08: ([0-9.e+-]+), above", caught.message)[1])
    assert measured == pytest.approx(expected, rel=0.05)
    assert caught.error > 100 * TIME_DEPENDENCE_RATIO  # against the autonomous twin


def test_a_right_first_order_method_passes_time_dependence(register: Any) -> None:
    """Its error on the driven block (h = 1e-5 s) is above the absolute bound, as on the
    autonomous twin x'' = -x: its order, not a stage at the wrong time (it failed)."""
    register(ForwardEuler)
    report = check_integrator(ForwardEuler, GYRO)
    passed = result(report, "time-dependence")
    assert passed.status == "pass", passed.message
    assert "above 1e-06" in passed.message and passed.error < 2.0


def test_a_method_ignoring_rtol_is_caught(register: Any) -> None:
    register(IgnoresRtol)
    report = check_integrator(IgnoresRtol, GYRO)
    assert result(report, "time-dependence").status == "pass"  # accurate ...
    deaf = result(report, "tolerance-response")  # ... but deaf to rtol
    assert deaf.status == "fail" and "ignores rtol" in deaf.message


def test_a_stub_fails_failure_and_metadata(register: Any) -> None:
    register(Stub)
    report = check_integrator(Stub, GYRO)
    assert result(report, "failure").status == "fail"
    assert "another reason than the blow-up" in result(report, "failure").message
    assert "placeholder" in result(report, "metadata").message


@pytest.mark.parametrize("name", ["rk4", "generalized-alpha", "rattle"])
def test_fixed_step_builtins_follow_rtol(name: str) -> None:
    """The fixed-step built-ins take their step from rtol (issue 22.4): the kit's
    tolerance response passes, with more steps at the tighter rtol."""
    report = check_integrator(name, GYRO)
    response = result(report, "tolerance-response")
    assert response.status == "pass", response.message
    assert result(report, "time-dependence").status == "pass"
