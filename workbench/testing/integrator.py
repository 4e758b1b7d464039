"""Conformance checks of an integrator plugin (:func:`check_integrator`).

Structural: registered, metadata, options, ``accepts`` (forms and indices). On problems
with an analytic reference (default: the torque-free symmetric gyro and the knife-edge
cart), over their first second, with a formalism offering a form the integrator accepts:

* ``accuracy`` — the end pose error (relative to the length scale) at the tight tolerance;
* ``convergence`` — tightening the tolerance does not make the error worse;
* ``statistics`` — output times as requested, states shaped like the form, counts filled.

Both analytic problems are autonomous, so a method evaluating its stages at wrong times
would pass them. On the driven block x'' = -sin t, x(0) = 0, x'(0) = 1 (solution
x = sin t, x' = cos t) over [0, 2] s:

* ``time-dependence`` — the end error at the tight tolerance is at most
  :data:`TIME_DEPENDENCE_ERROR` (an explicit midpoint evaluating its stage at t instead of
  t + h/2 is first order there and misses it by orders of magnitude), or, for a method
  of low order, at most :data:`TIME_DEPENDENCE_RATIO` times its error on the autonomous
  twin x'' = -x (the same solution, no t in the force);
* ``tolerance-response`` — tightening rtol from 1e-4 to 1e-8 changes the work done and
  reduces the error (by 10x at least, unless it is already below 100 x the tight rtol):
  a method that ignores rtol gives the same trajectory at both and fails.

``closed-loop`` (an integrator taking the ``dae`` or ``mechanical`` form at index 1 or
more, whose algebraic variables carry a closed loop's forces): the slider-crank (a
stored reference) over its first second in that form, the end pose error and the
position constraints' residual at the tight tolerance, each relative to the length
scale, at most :data:`CLOSED_LOOP_TOLERANCE`; both analytic problems above have no loop,
and a method that never solved for the multipliers passed them.

``failure``: on y'' = y'^2 (a blow-up at t = 1 from y' = 1) integrated to t = 2, the
integrator returns a failed trajectory with a reason and the time reached; it does not
raise and does not claim success, and it fails because of the blow-up: a method that
stops before t = 0.5 (a ``NotImplementedError`` stub, say) fails the check.
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np

from workbench.equations import FORMS, MechanicalSystem, build_joint_space_equations
from workbench.equations.initial import consistent_initial_state
from workbench.errors import ConfigError, one_line
from workbench.execution.references import given_reference
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import Model
from workbench.numerics.geometry import length_scale, pose_error
from workbench.plugin.formalism import ConstraintOptions
from workbench.plugin.integrator import Integrator
from workbench.plugin.registry import get_formalism
from workbench.testing.common import check_structure, problem_instances, resolve_plugin
from workbench.testing.report import ConformanceReport

ANALYTIC_PROBLEMS = ("torque-free-symmetric-gyro", "knife-edge-cart")
TOLERANCES = {"accuracy": 1e-4, "convergence": 1.5}  # relative error; growth factor allowed
RTOLS = (1e-4, 1e-8)
HORIZON = 1.0  # s
# s for the blow-up: a sweep's default time limit (runs/sweep_spec.py), reached by a hung
# run only: newmark's steps shrinking towards t = 1 took 43.5 s of CPU on a quiet Zen 3
# EPYC (2026-11-27), under 30 on the Zen 5 the kit was first run on
FAILURE_TIME_LIMIT = 120.0
CHECK_TIME_LIMIT = 300.0  # s a motion check may take; newmark's slowest took 5 s (Intel Xeon)
FAILURE_EARLIEST = 0.5  # s; y' = 1/(1 - t) is harmless up to here
DRIVEN_HORIZON = 2.0  # s
TIME_DEPENDENCE_ERROR = 1e-6  # |x - sin t| + |x' - cos t| at the end, at rtol 1e-8
# above it, driven error / the autonomous twin's (x'' = -x): a midpoint with its stage at
# t misses by 1e4 or more, a correct first-order method is within 1.2x
TIME_DEPENDENCE_RATIO = 10.0
RESPONSE_FACTOR = 10.0  # error reduction asked of 4 decades of rtol
CLOSED_LOOP = "slider-crank"
CLOSED_LOOP_TOLERANCE = 1e-4  # end pose error and |g(q)|, each / L, at rtol 1e-8 (as accuracy)


def check_integrator(
    integrator: str | type,
    problems: Any = None,
    options: dict[str, Any] | None = None,
    checks: str = "all",
    progress: Any = None,
) -> Any:
    """Check an integrator (registered name or class); returns a ConformanceReport.

    ``problems``: None (:data:`ANALYTIC_PROBLEMS`) or names / Problem instances with a
    reference. ``checks``: "structural" or "all". ``progress``: called with a line as each
    motion check starts (the CLI prints them). Each motion check runs in a forked process
    under :data:`CHECK_TIME_LIMIT`: a hung method is named, and the checks after it skipped.
    """
    if checks not in ("all", "structural"):
        raise ConfigError(f'checks must be "all" or "structural", not {checks!r}')
    plugin = resolve_plugin("integrator", integrator)
    report = ConformanceReport("integrator", getattr(plugin, "name", plugin.__qualname__))
    defaults = check_structure(report, "integrator", plugin, Integrator)
    accepts = getattr(plugin, "accepts", None)
    bad = (
        not isinstance(accepts, dict)
        or not accepts
        or any(k not in FORMS or v not in (0, 1, 2, 3) for k, v in accepts.items())
    )
    if bad:
        report.failed(
            "accepts",
            "",
            f"accepts must map some of {FORMS} to the highest dae index 0..3, got {accepts!r}",
        )
    else:
        report.passed("accepts", message=", ".join(f"{k} (<= {v})" for k, v in accepts.items()))
    if checks == "structural" or bad or defaults is None:
        return report
    steps = [(f"accuracy on {problem.name}", "accuracy", problem.name,
              lambda r, p=problem: _check_accuracy(r, plugin, options, p))
             for problem in problem_instances(problems or ANALYTIC_PROBLEMS)]  # fmt: skip
    if problems is None and any(accepts.get(f, 0) >= 1 for f in ("dae", "mechanical")):
        steps.append(("closed-loop on the slider-crank", "closed-loop", CLOSED_LOOP,
                      lambda r: _check_closed_loop(r, plugin, options)))  # fmt: skip
    steps += [
        ("time-dependence on the driven block", "time-dependence", "driven block x''=-sin t",
         lambda r: _check_time_dependence(r, plugin, options)),
        ("failure on the blow-up", "failure", "blow-up y''=y'^2",
         lambda r: _check_failure(r, plugin, options)),
    ]  # fmt: skip
    for i, (what, check, problem, run) in enumerate(steps):
        if progress is not None:
            progress(f"checking {what} ...")
        if check == "failure":  # under a limit of its own (FAILURE_TIME_LIMIT)
            run(report)
        elif not _within_time_limit(report, check, problem, run):
            for _what, later, later_problem, _run in steps[i + 1 :]:
                report.skipped(later, later_problem, "an earlier check did not finish in time")
            break
    return report


def _within_time_limit(report: ConformanceReport, check: str, problem: str, run: Any) -> bool:
    """``run(report)`` in a forked process under :data:`CHECK_TIME_LIMIT`, its results
    added to ``report``; False (with a failed result) when it did not finish in time."""
    part = ConformanceReport(report.kind, report.subject)
    try:
        results = with_time_limit(lambda: (run(part), part.results)[1], CHECK_TIME_LIMIT)
    except TimeoutError:
        report.failed(check, problem, f"did not finish within {CHECK_TIME_LIMIT:g} s: a hung "
                      "or very slow method (the checks after it are skipped)")  # fmt: skip
        return False
    report.results.extend(results)
    return True


def formalism_for(accepts: dict[str, int], model: Model) -> tuple[str, dict[str, Any]]:
    """A formalism and options offering a form ``accepts`` takes on ``model``."""
    if "ode" in accepts:
        name = "nonholonomic-projection" if model.nonholonomic else "minimal-ode"
        return name, ({} if model.nonholonomic else {"index": 1})
    index = min(accepts.get("dae", 3), 3) if "dae" in accepts else 3
    return "minimal-ode", {"index": max(index, 1)}


def _check_accuracy(report: ConformanceReport, plugin: type, options: Any, problem: Any) -> None:
    name = problem.name
    reference = given_reference(problem)
    if reference is None:
        report.skipped("accuracy", name, "the problem has no analytic or stored reference")
        return
    model = problem.model()
    formalism, formalism_options = formalism_for(plugin.accepts, model)
    equations = get_formalism(formalism)().build(model, formalism_options)
    integrator = plugin()
    offered = {key: getattr(form, "index", 0) for key, form in equations.forms.items()}
    form = integrator.select_form(offered)
    reason = integrator.incompatibility(equations, integrator.parse_options(options))
    if form is None or reason:
        report.skipped("accuracy", name, reason or f"no accepted form in {offered}")
        return
    state = consistent_initial_state(equations, problem)
    times = problem.sample_times()
    times = times[times <= times[0] + HORIZON + 1e-12]
    expected = np.asarray(reference.poses(times), float)
    length = length_scale(model, expected)
    errors = []
    for rtol in RTOLS:
        trajectory = integrator.solve(
            equations,
            state.y0(equations, form),
            state.yp0(equations, form),
            times,
            rtol,
            rtol * 1e-3,
            options,
            form,
        )
        if not trajectory.success:
            report.failed("accuracy", name, f"rtol {rtol:g}: {trajectory.message}")
            return
        _check_statistics(report, name, trajectory, times, equations.forms[form], rtol)
        poses = equations.observables.poses(times[-1], trajectory.y[-1, : equations.nq])[None]
        errors.append(float(pose_error(poses, expected[-1:], length)[0]) / length)
    setup = f"{formalism} {formalism_options}, {form} form, {times[-1] - times[0]:g} s"
    report.add(
        "accuracy",
        name,
        errors[-1],
        TOLERANCES["accuracy"],
        f"end pose error / L at rtol {RTOLS[-1]:g} ({setup})",
    )
    growth = errors[-1] / max(errors[0], 1e-14)
    report.add(
        "convergence",
        name,
        growth,
        TOLERANCES["convergence"],
        f"error at rtol {RTOLS[-1]:g} / at {RTOLS[0]:g}: {errors[-1]:.1e} / {errors[0]:.1e}",
    )


def _check_closed_loop(report: ConformanceReport, plugin: type, options: Any) -> None:
    """The ``closed-loop`` check (module docstring), in the ``dae`` form if accepted, else
    the ``mechanical`` one; nothing for an integrator that takes neither."""
    accepts = plugin.accepts
    form = next((f for f in ("dae", "mechanical") if accepts.get(f, 0) >= 1), None)
    if form is None:  # (index 0: no constraints taken, as the contact methods')
        return
    (problem,) = problem_instances([CLOSED_LOOP])
    model = problem.model()
    index = min(accepts[form], 3) if form == "dae" else 3
    equations = get_formalism("minimal-ode")().build(model, {"index": index})
    integrator = plugin()
    reason = integrator.incompatibility(equations, integrator.parse_options(options))
    if reason:
        report.skipped("closed-loop", CLOSED_LOOP, reason)
        return
    state = consistent_initial_state(equations, problem)
    times = problem.sample_times()
    times = times[times <= times[0] + HORIZON + 1e-12]
    rtol = RTOLS[-1]
    trajectory = integrator.solve(equations, state.y0(equations, form),
                                  state.yp0(equations, form), times, rtol, rtol * 1e-3,
                                  options, form)  # fmt: skip
    if not trajectory.success:
        report.failed("closed-loop", CLOSED_LOOP, f"rtol {rtol:g}: {trajectory.message}")
        return
    expected = np.asarray(given_reference(problem).poses(times[-1:]), float)
    length = length_scale(model, expected)
    nq, nv = equations.nq, equations.nv
    sampled = equations.observables.along(times[-1:], trajectory.y[-1:, :nq],
                                          trajectory.y[-1:, nq : nq + nv])  # fmt: skip
    error = float(pose_error(sampled.poses, expected, length)[0]) / length
    residual = float(np.abs(sampled.residuals[0]).max()) / length
    setup = f"minimal-ode index {index}, {form} form, {times[-1] - times[0]:g} s, rtol {rtol:g}"
    report.add("closed-loop", CLOSED_LOOP, max(error, residual), CLOSED_LOOP_TOLERANCE,
               f"end pose error / L {error:.1e}, position constraints' residual / L "
               f"{residual:.1e} ({setup}; the multipliers hold the loop together)")  # fmt: skip


def _check_statistics(
    report: ConformanceReport, name: str, trajectory: Any, times: np.ndarray, form: Any, rtol: float
) -> None:
    problems = []
    if not np.allclose(trajectory.times, times):
        problems.append("output times differ from the requested ones")
    n = getattr(form, "n", None) or trajectory.y.shape[1]
    if np.shape(trajectory.y) != (times.size, n):
        problems.append(f"y has shape {np.shape(trajectory.y)}, expected {(times.size, n)}")
    stats = trajectory.stats
    if stats.n_steps <= 0 and stats.n_rhs <= 0:
        problems.append("neither n_steps nor n_rhs counted (set trajectory.stats.n_steps)")
    if problems:
        report.failed("statistics", name, f"rtol {rtol:g}: " + "; ".join(problems))
    elif rtol == RTOLS[-1]:
        report.passed(
            "statistics",
            name,
            f"{stats.n_steps} steps, {stats.n_rhs} rhs, "
            f"{stats.n_jac} Jacobians, {stats.n_rejected} rejected",
        )


def with_time_limit(function: Any, seconds: float) -> Any:
    """``function()`` in a forked child process; TimeoutError if it takes longer.

    Without fork (not POSIX) it runs here, unlimited.
    """
    import multiprocessing

    try:
        context = multiprocessing.get_context("fork")
    except ValueError:
        return function()
    receiver, sender = context.Pipe(duplex=False)

    def child() -> None:
        try:
            sender.send((True, function()))
        except BaseException as error:  # noqa: BLE001 - sent back to the parent
            sender.send((False, error))

    process = context.Process(target=child, daemon=True)
    process.start()
    ready = receiver.poll(seconds)
    if not ready:
        process.kill()
        process.join()
        raise TimeoutError
    ok, value = receiver.recv()
    process.join()
    if not ok:
        raise value
    return value


def blow_up_equations() -> Any:
    """Equations of y'' = y'^2 (a block on a prismatic joint), y'(0) = 1: y' = 1/(1 - t)."""
    model = Model("blow-up", kind="planar", gravity=(0.0, 0.0, 0.0))
    model.add_body("block", 1.0, inertia=1.0)
    model.add_joint("slide", "prismatic", "ground", "block", axis=(1, 0, 0))
    k = TreeKinematics(model)
    system = MechanicalSystem(k.t, k.q, k.v, k.qdot, ca.SX.eye(1), k.v**2, k.q_names, k.v_names)
    return build_joint_space_equations("blow-up", model, k, system, ConstraintOptions(), True)


def driven_equations(autonomous: bool = False) -> Any:
    """Equations of a unit mass on a prismatic joint pushed by the force -sin(t) N:
    x'' = -sin t; from x(0) = 0, x'(0) = 1 the solution is x = sin t, x' = cos t.
    ``autonomous``: its twin on a unit spring, x'' = -x, with the same solution."""
    name = "spring-block" if autonomous else "driven-block"
    model = Model(name, kind="planar", gravity=(0.0, 0.0, 0.0))
    model.add_body("block", 1.0, inertia=1.0)
    model.add_joint("slide", "prismatic", "ground", "block", axis=(1, 0, 0))
    k = TreeKinematics(model)
    force = -k.q if autonomous else -ca.sin(k.t)
    system = MechanicalSystem(k.t, k.q, k.v, k.qdot, ca.SX.eye(1), force, k.q_names, k.v_names)
    return build_joint_space_equations(name, model, k, system, ConstraintOptions(), True)


def _first_two(equations: Any, form: str, values: tuple[float, float]) -> np.ndarray:
    """A state of ``form`` whose first two components (x, x') are ``values``, zeros after."""
    n = equations.forms[form].n if form != "mechanical" else 2
    y = np.zeros(n)
    y[:2] = values
    return y


def _check_time_dependence(report: ConformanceReport, plugin: type, options: Any) -> None:
    where = "driven block x''=-sin t"
    equations = driven_equations()
    integrator = plugin()
    offered = {key: getattr(form, "index", 0) for key, form in equations.forms.items()}
    form = integrator.select_form(offered)
    reason = integrator.incompatibility(equations, integrator.parse_options(options))
    if form is None or reason:
        for check in ("time-dependence", "tolerance-response"):
            report.skipped(check, where, reason or f"no accepted form in {offered}")
        return
    y0 = _first_two(equations, form, (0.0, 1.0))
    yp0 = _first_two(equations, form, (1.0, 0.0))
    times = np.linspace(0.0, DRIVEN_HORIZON, 21)
    exact = np.array([np.sin(times[-1]), np.cos(times[-1])])
    runs = []
    for rtol in RTOLS:
        try:
            trajectory = integrator.solve(
                equations, y0, yp0, times, rtol, rtol * 1e-3, options, form
            )
        except Exception as error:  # noqa: BLE001
            report.failed("time-dependence", where, f"solve raised: {one_line(error)}")
            return
        if not trajectory.success:
            report.failed("time-dependence", where, f"rtol {rtol:g}: {trajectory.message}")
            return
        error = float(np.abs(np.asarray(trajectory.y)[-1, :2] - exact).sum())
        runs.append((rtol, error, trajectory))
    (loose, loose_error, loose_run), (tight, tight_error, tight_run) = runs
    measured = f"|x - sin t| + |x' - cos t| at t = {DRIVEN_HORIZON:g} s, rtol {tight:g}"
    if tight_error <= TIME_DEPENDENCE_ERROR:
        report.add("time-dependence", where, tight_error, TIME_DEPENDENCE_ERROR,
                   f"{measured} (a stage evaluated at the wrong time shows here)")  # fmt: skip
    else:  # a low order, or a stage at the wrong time: the autonomous twin tells them apart
        twin = driven_equations(autonomous=True)
        trajectory = integrator.solve(twin, y0, _first_two(twin, form, (0.0, 0.0)), times,
                                      tight, tight * 1e-3, options, form)  # fmt: skip
        twin_error = float(np.abs(np.asarray(trajectory.y)[-1, :2] - exact).sum())
        if not trajectory.success or not np.isfinite(twin_error):
            twin_error = math.inf
        report.add("time-dependence", where, tight_error / max(twin_error, 1e-300),
                   TIME_DEPENDENCE_RATIO,
                   f"{measured}: {tight_error:.2e}, above {TIME_DEPENDENCE_ERROR:g}; on its "
                   f"autonomous twin x'' = -x, the same solution: {twin_error:.2e}. Several "
                   "times more error when the force depends on t is a stage evaluated at "
                   "the wrong time; the same error is the method's own order")  # fmt: skip
    work = [(r.stats.n_steps, r.stats.n_rhs) for r in (loose_run, tight_run)]
    same = work[0] == work[1] and np.array_equal(loose_run.y, tight_run.y)
    floor = 100 * tight
    if same:
        report.failed(
            "tolerance-response",
            where,
            f"identical trajectories and work ({work[0][0]} steps, {work[0][1]} rhs) at rtol "
            f"{loose:g} and {tight:g}: the method ignores rtol; map rtol to a step by a "
            "documented rule, or make the step an option the user sets and say so",
        )
    elif tight_error > loose_error / RESPONSE_FACTOR and tight_error > floor:
        report.failed(
            "tolerance-response",
            where,
            f"error {loose_error:.2e} at rtol {loose:g} and {tight_error:.2e} at {tight:g}: "
            f"4 decades of rtol bought less than {RESPONSE_FACTOR:g}x",
        )
    else:
        report.passed(
            "tolerance-response",
            where,
            f"error {loose_error:.1e} -> {tight_error:.1e}, steps {work[0][0]} -> {work[1][0]}",
        )


def _check_failure(report: ConformanceReport, plugin: type, options: Any) -> None:
    equations = blow_up_equations()
    integrator = plugin()
    offered = {key: getattr(form, "index", 0) for key, form in equations.forms.items()}
    form = integrator.select_form(offered)
    reason = integrator.incompatibility(equations, integrator.parse_options(options))
    if form is None or reason:
        report.skipped("failure", "", reason or f"no accepted form in {offered}")
        return
    n = equations.forms[form].n if form != "mechanical" else 2
    y0, yp0 = np.zeros(n), np.zeros(n)
    y0[1], yp0[:2] = 1.0, [1.0, 1.0]
    times = np.linspace(0.0, 2.0, 21)
    try:
        trajectory = with_time_limit(
            lambda: integrator.solve(equations, y0, yp0, times, 1e-6, 1e-9, options, form),
            FAILURE_TIME_LIMIT,
        )
    except TimeoutError:
        report.failed(
            "failure",
            "blow-up y''=y'^2",
            f"no answer within {FAILURE_TIME_LIMIT:g} s "
            "(a sweep would record a timeout): stop on a step size underflow or a "
            "maximum number of steps",
        )
        return
    except Exception as error:  # noqa: BLE001
        report.failed("failure", "", f"solve raised instead of failing: {one_line(error)}")
        return
    problems = []
    if trajectory.success:
        problems.append("claimed success through a blow-up at t = 1")
    if not trajectory.message:
        problems.append("no message saying why it failed")
    if not trajectory.t_reached < 2.0:
        problems.append(f"t_reached = {trajectory.t_reached}, expected < 2")
    elif not trajectory.t_reached >= FAILURE_EARLIEST:
        problems.append(
            f"it stopped at t = {trajectory.t_reached:g}, before the solution grows "
            f"(t < {FAILURE_EARLIEST:g}): it failed for another reason than the blow-up"
        )
    if problems:
        said = f" (its message: {trajectory.message[:160]})" if trajectory.message else ""
        report.failed("failure", "blow-up y''=y'^2", "; ".join(problems) + said)
    else:
        report.passed(
            "failure",
            "blow-up y''=y'^2",
            f"t reached {trajectory.t_reached:g}: {trajectory.message[:80]}",
        )
