"""The heyoka Taylor integrator and the CasADi -> heyoka translator.

Oracles: the CasADi Function itself (the translated graph, compiled by heyoka, must give
the same numbers at random states); the simple pendulum's exact motion through Jacobi
elliptic functions (14 correct digits at a tolerance near machine precision); the
integrator conformance kit.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

hy = pytest.importorskip("heyoka")

from workbench.equations.initial import consistent_initial_state  # noqa: E402
from workbench.plugin.registry import get_formalism, get_integrator, get_problem  # noqa: E402
from workbench.plugins.integrators._casadi_heyoka import TranslationError, translate  # noqa: E402
from workbench.problems.simple_pendulum import exact_solution  # noqa: E402
from workbench.testing import check_integrator  # noqa: E402


def _compiled(function: ca.Function, n: int):
    """heyoka's compiled function of the translated ``function`` (t, y) -> [outputs]."""
    variables = list(hy.make_vars(*[f"y{i}" for i in range(n)]))
    outputs = translate(function, [[hy.time], variables])
    return hy.cfunc([e for output in outputs for e in output], vars=variables)


def test_every_supported_operation_agrees_with_casadi():
    t, y = ca.SX.sym("t"), ca.SX.sym("y", 3)
    a, b, c = y[0], y[1], y[2]
    expressions = [
        a + b, a - b, a * b, a / b, -a, a**2, 2 * a, 1 / a, ca.sqrt(ca.fabs(a)), ca.sin(a),
        ca.cos(a), ca.tan(a), ca.asin(a / 4), ca.acos(a / 4), ca.atan(a), ca.sinh(a),
        ca.cosh(a), ca.tanh(a), ca.asinh(a), ca.acosh(1 + a * a), ca.atanh(a / 4), ca.exp(a),
        ca.log(1 + a * a), ca.expm1(a), ca.log1p(a * a), ca.erf(a), ca.fabs(b), ca.sign(b),
        ca.power(ca.fabs(a) + 1, b), ca.constpow(a, 3), ca.atan2(a, b), ca.hypot(a, b),
        ca.fmin(a, b), ca.fmax(a, b), ca.if_else(a < b, c, t), ca.if_else(a <= b, t, c),
        ca.if_else(ca.logic_and(a > 0, b > 0), 1, 2), ca.if_else(ca.logic_or(a > 0, b > 0), 1, 2),
        ca.if_else(ca.logic_not(a > 0), 3, 4), ca.if_else(a == a, 5, 6), ca.if_else(a != b, 7, 8),
        ca.copysign(a, b), t * a, 3.25,
    ]  # fmt: skip
    function = ca.Function("many", [t, y], [ca.densify(ca.vertcat(*expressions))])
    compiled = _compiled(function, 3)
    rng = np.random.default_rng(1)
    for _ in range(50):
        state, time = rng.uniform(-2, 2, 3), float(rng.uniform(-1, 1))
        expected = np.asarray(function(time, state)).ravel()
        got = compiled(state, time=time)
        np.testing.assert_allclose(got, expected, rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize(
    ("problem", "formalism", "options", "relative"),
    [
        ("double-pendulum", "recursive", {}, 1e-14),
        # the rotation's division by p^T p: 1.05e-14 of the largest component (measured)
        ("heavy-top", "recursive", {}, 2e-14),
        ("heavy-top", "minimal-ode", {"index": 1}, 1e-14),
        ("rolling-pendulum", "minimal-ode", {"index": 1}, 1e-14),
        # 1,559 instructions whose own round-off is about 1e-14: CasADi's double evaluation
        # differs from an extended-precision one by up to 1.2e-14 (measured)
        ("spatial-chain", "recursive", {}, 3e-14),
    ],
)
def test_translated_equations_agree_with_casadi_at_random_states(
    problem, formalism, options, relative
):
    """The ode right-hand side of a formalism, translated and compiled by heyoka, gives
    CasADi's numbers to 1e-14 relative (of the largest component) at random states near
    the initial one."""
    instance = get_problem(problem)()
    equations = get_formalism(formalism)().build(instance.model(), options)
    form = equations.forms["ode"]
    compiled = _compiled(form.rhs.function, form.n)
    y0 = consistent_initial_state(equations, instance).y0(equations, "ode")
    rng = np.random.default_rng(2)
    for _ in range(20):
        state, time = y0 + 0.01 * rng.normal(size=form.n), float(rng.uniform(0, 1))
        expected = np.asarray(form.rhs.function(time, state)).ravel()
        got = compiled(state, time=time)
        scale = np.max(np.abs(expected))
        assert np.max(np.abs(got - expected)) <= relative * scale


def test_an_operation_without_a_heyoka_counterpart_is_named():
    t, y = ca.SX.sym("t"), ca.SX.sym("y")
    function = ca.Function("floor", [t, y], [ca.floor(y)])
    with pytest.raises(TranslationError, match="floor"):
        translate(function, [[hy.time], [hy.make_vars("y")]])


@pytest.mark.parametrize("precision", ["double", "extended"])
def test_simple_pendulum_to_fourteen_digits(precision):
    """At tol 1e-15 the angle agrees with the exact elliptic-function motion to 14 digits
    over 10 s (about 5 periods); at tol 1e-8 it does not reach 12: the error follows the
    tolerance asked for."""
    problem = get_problem("simple-pendulum")()
    equations = get_formalism("minimal-ode")().build(problem.model(), {"index": 1})
    y0 = consistent_initial_state(equations, problem).y0(equations, "ode")
    times = np.linspace(0.0, problem.t_end, 41)
    theta0 = problem.options.initial_angle
    exact = exact_solution(times, theta0, 1.0, 9.81)
    errors = {}
    for tol in (1e-8, 1e-15):
        trajectory = get_integrator("heyoka-taylor")().solve(
            equations, y0, None, times, tol, tol, {"precision": precision}
        )
        assert trajectory.success, trajectory.message
        errors[tol] = np.max(np.abs(trajectory.y[:, 0] - exact)) / theta0
    assert errors[1e-15] < 1e-14
    assert errors[1e-8] > 1e-12


def test_passes_the_integrator_conformance_checks():
    check_integrator("heyoka-taylor").raise_if_failed()


def test_bad_precision_is_one_clear_line():
    from workbench.errors import ConfigError

    with pytest.raises(ConfigError, match="precision must be one of"):
        get_integrator("heyoka-taylor").parse_options({"precision": "octuple"})


def test_plugin_discovery_does_not_import_heyoka() -> None:
    """heyoka and the SymPy it imports (100 MiB and more) are loaded by a heyoka run only:
    every sweep's parent, its forked workers and its report discover the plugins (issue 35)."""
    import subprocess
    import sys

    probe = (
        "import sys\nfrom workbench.plugin import registry\n"
        "registry.get_integrator('heyoka-taylor')\nregistry.get_problem('four-bar')\n"
        "print(sorted({'heyoka', 'sympy'} & set(sys.modules)))"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]", done.stdout + done.stderr
