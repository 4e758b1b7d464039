"""The conformance suite (workbench.testing) passes the real plugins and catches wrong
ones, naming the check, the problem and the size of the error."""

import math

import casadi as ca
import numpy as np
import pytest

from workbench.equations import build_joint_space_equations
from workbench.mechanics.kinematics import TreeKinematics
from workbench.plugin.integrator import Integrator
from workbench.plugin.problem import Invariant, Reference
from workbench.plugin.registry import REGISTRY, PluginInfo
from workbench.plugins.formalisms.minimal_ode import MinimalOde, minimal_mechanical_system
from workbench.testing import (
    ConformanceError,
    check_formalism,
    check_integrator,
    check_problem,
)
from workbench.testing.__main__ import main


@pytest.fixture
def register(monkeypatch):
    """Register plugin classes in the global registry for one test."""
    REGISTRY.discover()

    def add(kind, plugin):
        info = PluginInfo(kind, plugin.name, plugin, plugin.__module__)
        monkeypatch.setitem(REGISTRY.entries[kind], plugin.name, info)
        return plugin

    return add


class ChangedForces(MinimalOde):
    """minimal-ode with its generalized forces changed by :meth:`changed` (a test's bug)."""

    def changed(self, system):
        raise NotImplementedError

    def build(self, model, options=None):
        options = self.parse_options(options)
        kinematics = TreeKinematics(model)
        system = minimal_mechanical_system(model, kinematics)
        system.forces = self.changed(system)
        ode = system.n_constraints == 0 or options.index == 1
        return build_joint_space_equations(self.name, model, kinematics, system, options, ode)


class ScaledForces(ChangedForces):
    """minimal-ode with every generalized force 1 % too large (a deliberate bug)."""

    name = "test-scaled-forces"
    summary = "minimal-ode with forces 1 % too large (test)"

    def changed(self, system):
        return 1.01 * system.forces


class WrongJacobian(MinimalOde):
    """minimal-ode whose ode Jacobian is twice the true one (a deliberate bug)."""

    name = "test-wrong-jacobian"
    summary = "minimal-ode with a wrong ode Jacobian (test)"

    def build(self, model, options=None):
        equations = super().build(model, options)
        jacobian = equations.forms["ode"].jacobian
        equations.forms["ode"].jacobian = lambda t, y: (2.0 * jacobian(t, y)[0],)
        return equations


class LateNan(ChangedForces):
    """minimal-ode whose forces turn NaN after t = 0.5 s (beyond the kit's short run)."""

    name = "test-late-nan"
    summary = "minimal-ode with NaN forces after 0.5 s (test)"

    def changed(self, system):
        return system.forces + ca.if_else(system.t > 0.5, math.nan, 0.0)


def failure(report, check, problem=""):
    found = [r for r in report.failures if r.check == check and r.problem == problem]
    assert found, f"expected a {check} failure on {problem!r} in\n{report}"
    return found[0]


def test_real_formalism_passes_everything():
    report = check_formalism("minimal-ode", options={"index": 1})
    report.raise_if_failed()
    checks = {r.check for r in report.results if r.status == "pass"}
    assert {"accelerations", "jacobian-ode", "energy", "invariants", "trajectory"} <= checks


def test_a_force_error_of_one_percent_is_caught_with_its_size(register):
    register("formalism", ScaledForces)
    report = check_formalism(ScaledForces, ["double-pendulum"], {"index": 1})
    wrong = failure(report, "accelerations", "double-pendulum")
    assert 1e-3 < wrong.error < 0.1 and wrong.tolerance == 1e-8
    assert "vs recursive" in wrong.message or "vs minimal-ode" in wrong.message
    failure(report, "energy", "double-pendulum")
    # the same state gives the same poses and energies: only the dynamics are wrong
    assert all(r.status == "pass" for r in report.results if r.check == "observables")
    with pytest.raises(ConformanceError, match=r"FAIL  accelerations .* double-pendulum"):
        report.raise_if_failed()


def test_a_wrong_jacobian_is_caught(register):
    register("formalism", WrongJacobian)
    report = check_formalism(WrongJacobian, ["simple-pendulum"], checks=["jacobians"])
    wrong = failure(report, "jacobian-ode", "simple-pendulum")
    assert wrong.error > 0.1
    assert not any(
        r.check.startswith("jacobian-") and r.status == "fail" and r.check != "jacobian-ode"
        for r in report.results
    )


def test_structural_failures_name_what_to_fix():
    class Nameless(MinimalOde):
        name = "Not A Name"
        summary = ""
        capabilities = frozenset({"planar", "warp-drive"})

    report = check_formalism(Nameless, checks="structural")
    assert "lowercase" in failure(report, "metadata").message
    assert "summary" in failure(report, "metadata").message
    assert "warp-drive" in failure(report, "capabilities").message
    assert "@workbench.plugin.registry.formalism" in failure(report, "registered").message
    assert not any(r.problem for r in report.results)  # nothing was built


def test_unsupported_problems_are_skipped_with_the_reason():
    report = check_formalism("recursive", ["rolling-pendulum"])
    (skip,) = [r for r in report.results if r.status == "skip"]
    assert skip.check == "supported" and "nonholonomic" in skip.message


class CoarseEuler(Integrator):
    """Explicit Euler with a 10 ms step, whatever the tolerance: inaccurate (test)."""

    name = "test-coarse-euler"
    summary = "explicit Euler, 10 ms steps (test)"
    accepts = {"ode": 0}

    def integrate(self, task, trajectory):
        rhs, y, t = task.form.rhs, task.y0.copy(), task.times[0]
        out = [y.copy()]
        for t_next in task.times[1:]:
            while t < t_next - 1e-12:
                h = min(1e-2, t_next - t)
                y = y + h * rhs(t, y)[0]
                t += h
            out.append(y.copy())
        trajectory.times, trajectory.y = task.times, np.array(out)
        trajectory.stats.n_steps = len(task.times)


class Clamped(CoarseEuler):
    """Clamps the state so it never blows up, hiding the failure (test)."""

    name = "test-clamped"
    summary = "hides a blow-up by clamping (test)"

    def integrate(self, task, trajectory):
        super().integrate(task, trajectory)
        trajectory.y = np.clip(np.nan_to_num(trajectory.y), -1e3, 1e3)


def test_real_integrator_passes():
    check_integrator("scipy-dop853").raise_if_failed()


def test_an_inaccurate_integrator_fails_accuracy_with_its_error(register):
    register("integrator", CoarseEuler)
    report = check_integrator(CoarseEuler, ["torque-free-symmetric-gyro"])
    wrong = failure(report, "accuracy", "torque-free-symmetric-gyro")
    assert wrong.error > 1e-4 and "rtol 1e-08" in wrong.message


def test_an_integrator_hiding_a_blow_up_fails_the_failure_check(register):
    register("integrator", Clamped)
    report = check_integrator(Clamped, ["torque-free-symmetric-gyro"])
    assert "claimed success" in failure(report, "failure", "blow-up y''=y'^2").message


def test_real_problems_pass_including_an_analytic_reference():
    check_problem("rotating-ring").raise_if_failed()
    gyro = check_problem("torque-free-symmetric-gyro").raise_if_failed()
    (reference,) = [r for r in gyro.results if r.check == "reference"]
    assert reference.status == "pass" and reference.error < 1e-8


def test_a_reference_with_unknown_orientations_is_checked_on_positions():
    # the rolling ball's reference knows the centre's circle, not the ball's orientation
    report = check_problem("ball-on-rotating-plane").raise_if_failed()
    (reference,) = [r for r in report.results if r.check == "reference"]
    assert reference.status == "pass" and reference.error < 1e-8
    vectorized = [r for r in report.results if r.check == "vectorized-invariant"]
    assert len(vectorized) == 3 and all(r.status == "pass" for r in vectorized)


def test_an_invariant_declared_vectorized_that_does_not_broadcast_is_caught(register):
    from workbench.problems.ch4_gyros import TorqueFreeSymmetricGyro

    def spin_rate(model, t, poses, twists):  # the norm of every sample at once: a scalar
        return np.linalg.norm(np.asarray(twists)[..., 0, 3:6])

    class FlatGyro(TorqueFreeSymmetricGyro):
        name = "test-flat-gyro"

        def invariants(self):
            return [Invariant("spin_rate", spin_rate, vectorized=True)]

    register("problem", FlatGyro)
    wrong = failure(check_problem(FlatGyro), "invariants", "test-flat-gyro")
    assert "declared vectorized but returned shape ()" in wrong.message


def test_a_wrong_analytic_reference_is_caught_with_its_error(register):
    from workbench.problems.ch4_gyros import TorqueFreeSymmetricGyro

    class SlowGyro(TorqueFreeSymmetricGyro):
        name = "test-slow-gyro"

        def reference(self):
            right = super().reference()
            return Reference("analytic", lambda times: right.poses(0.99 * np.asarray(times)))

    register("problem", SlowGyro)
    wrong = failure(check_problem(SlowGyro), "reference", "test-slow-gyro")
    assert 1e-5 < wrong.error < 1.0


def test_a_failed_tight_run_is_a_fail_row_and_the_other_checks_go_on(register, capsys):
    from workbench.model.elements import JointForce
    from workbench.problems.ch4_gyros import TorqueFreeSymmetricGyro

    def late_nan(t, q, v):  # the kit's run (0.5 s) cannot finish
        return ca.if_else(t > 0.1, math.nan, 0.0) * ca.DM.ones(3)

    class LateNanGyro(TorqueFreeSymmetricGyro):
        """The symmetric gyro with a pivot torque that is NaN after 0.1 s (a test's bug)."""

        name = "test-late-nan-gyro"
        conservative = False

        def model(self):
            model = super().model()
            model.add_force(JointForce("late-nan", "pivot", late_nan))
            return model

    register("problem", LateNanGyro)
    report = check_problem(LateNanGyro)
    run = failure(report, "tight-run", "test-late-nan-gyro")
    assert "tight run failed" in run.message and "DOP853" in run.message
    # the reference was still called and checked for shape, only not compared
    (reference,) = [r for r in report.results if r.check == "reference"]
    assert reference.status == "skip" and "well shaped" in reference.message
    assert [r.status for r in report.results if r.check == "invariants"] == ["skip"]
    assert main(["problem", "test-late-nan-gyro"]) == 1  # a failure, not bad input (2)
    assert "FAIL  tight-run" in capsys.readouterr().out


def test_command_line_prints_the_report_and_exits_1_on_failure(register, capsys):
    register("formalism", ScaledForces)
    assert (
        main(["formalism", "test-scaled-forces", "--problems", "simple-pendulum", "--failures"])
        == 1
    )
    out = capsys.readouterr().out
    assert "FAIL  accelerations" in out and "simple-pendulum" in out
    assert main(["formalism", "nope"]) == 2


def test_the_summary_says_over_what_span_the_trajectory_was_checked(register):
    """A formalism whose forces turn NaN after 0.5 s passes the kit's 0.2 s run and fails
    every run of a sweep: the summary says how far its PASS reaches."""
    register("formalism", LateNan)
    report = check_formalism("test-late-nan", ["double-pendulum"])
    assert report.ok, str(report)
    span = "trajectory checked over 0.2 s, not a run's whole time span"
    assert report.summary().endswith(f"0 failed, 0 skipped; {span}")
    longer = check_formalism("test-late-nan", ["double-pendulum"], checks=["motion"], horizon=0.4)
    assert "trajectory checked over 0.4 s" in longer.summary()
    assert "checked over" not in check_formalism("test-late-nan", checks="structural").summary()


def test_a_formalisms_failed_tight_run_is_a_fail_row_not_a_skip(register):
    """Over 0.8 s the NaN forces are reached: the formalism's own run failing is a finding
    (it read 'SKIP energy' and the report passed); the other checks stand."""
    register("formalism", LateNan)
    report = check_formalism("test-late-nan", ["double-pendulum"], horizon=0.8)
    run = failure(report, "tight-run", "double-pendulum")
    assert "DOP853 rtol 1e-10 over 0.8 s" in run.message and "not checked" in run.message
    assert not report.ok and [r.check for r in report.failures] == ["tight-run"]
    assert any(r.check == "accelerations" and r.status == "pass" for r in report.results)
    # a formalism without an ode form is not a failure: nothing to run
    index3 = check_formalism("absolute-dae", ["double-pendulum"], {"index": 3}, checks=["motion"])
    (energy,) = [r for r in index3.results if r.check == "energy"]
    assert energy.status == "skip" and "built no ode form" in energy.message


class FrozenMultipliers(Integrator):
    """Backward Euler on the dae form whose Newton solves only the differential
    equations: the algebraic variables (the multipliers) keep their first values (test)."""

    name = "test-frozen-multipliers"
    summary = "backward Euler leaving the algebraic variables alone (test)"
    accepts = {"dae": 1}

    def integrate(self, task, trajectory):
        residual, jacobian = task.form.residual, task.form.jacobian
        differential = ~np.asarray(task.form.algebraic, bool)
        y, out = task.y0.copy(), [task.y0.copy()]
        for t0, t1 in zip(task.times[:-1], task.times[1:], strict=True):
            n = max(1, math.ceil((t1 - t0) / 1e-3))
            h = (t1 - t0) / n
            for i in range(n):
                z = y.copy()
                for _ in range(4):
                    (r,) = residual(t0 + (i + 1) * h, z, (z - y) / h)
                    (J,) = jacobian(t0 + (i + 1) * h, z, (z - y) / h, 1.0 / h)
                    J = np.asarray(J.toarray() if hasattr(J, "toarray") else J)
                    block = J[np.ix_(differential, differential)]
                    z[differential] -= np.linalg.solve(block, np.ravel(r)[differential])
                y = z
            out.append(y.copy())
        trajectory.times, trajectory.y = task.times, np.array(out)
        trajectory.stats.n_steps = len(task.times)


def test_a_dae_method_that_never_solves_for_the_multipliers_fails_the_closed_loop(register):
    """Both analytic problems have no loop: such a method passed their accuracy; on the
    slider-crank its links come apart, while IDA holds them together."""
    from workbench.testing.integrator import CLOSED_LOOP, _check_closed_loop
    from workbench.testing.report import ConformanceReport

    register("integrator", FrozenMultipliers)
    reports = {}
    for plugin in (FrozenMultipliers, REGISTRY.get("integrator", "sundials-ida")):
        reports[plugin.name] = ConformanceReport("integrator", plugin.name)
        _check_closed_loop(reports[plugin.name], plugin, None)
    wrong = failure(reports["test-frozen-multipliers"], "closed-loop", CLOSED_LOOP)
    assert wrong.error > 1e-2 and "position constraints' residual" in wrong.message
    (right,) = reports["sundials-ida"].results
    assert right.status == "pass" and right.error < 1e-5, right.message


class Sleeper(CoarseEuler):
    """Never returns from its first solve (test)."""

    name = "test-sleeper"
    summary = "sleeps (test)"

    def integrate(self, task, trajectory):
        import time

        time.sleep(600)


def test_a_hung_integrator_is_named_by_the_check_it_hangs_in(register, monkeypatch):
    """The kit printed nothing and never ended on a hung method: each motion check now
    says it starts and runs under a time limit; the checks after a hung one are skipped."""
    from workbench.testing import integrator as kit

    monkeypatch.setattr(kit, "CHECK_TIME_LIMIT", 2.0)
    register("integrator", Sleeper)
    started = []
    report = check_integrator(Sleeper, ["torque-free-symmetric-gyro"], progress=started.append)
    hung = failure(report, "accuracy", "torque-free-symmetric-gyro")
    assert "did not finish within 2 s" in hung.message
    assert started == ["checking accuracy on torque-free-symmetric-gyro ..."]
    skipped = {(r.check, r.status) for r in report.results if r.check != "accuracy"}
    assert {("time-dependence", "skip"), ("failure", "skip")} <= skipped
    with pytest.raises(Exception, match='checks must be "all" or "structural"'):
        check_integrator(Sleeper, checks=["accuracy"])
