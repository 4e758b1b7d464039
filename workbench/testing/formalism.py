"""Conformance checks of a formalism plugin (:func:`check_formalism`).

Structural (no physics needed): registered, metadata, options, capabilities, forms.
Per catalog problem whose features the formalism supports (physics is the oracle):

* ``build`` — builds, and the :class:`~workbench.equations.Equations` have consistent
  sizes and the declared forms (``equations``);
* ``dof`` — the equations keep the degrees of freedom ``workbench describe`` finds (nv
  minus the rank of their constraint rows at the consistent initial state): no row that
  is independent at the problem's initial configuration was removed;
* ``observables`` — at random consistent states, body poses, twists and energies equal
  those of a reference formalism at the same physical state (same quantities, same units);
* ``accelerations`` — the time derivatives of the body twists agree with the reference;
* ``jacobian-ode``, ``jacobian-dae``, ``jacobian-mechanical`` — exact Jacobians match
  central finite differences;
* over a short tight integration of the ode form: ``energy`` (conservative problems),
  ``invariants``, ``constraints`` (residual drift) and ``trajectory`` (end poses against
  the reference formalism's).

A formalism that enforces its constraints approximately (a penalty or augmented-Lagrangian
method) declares it with ``constraint_tolerance(options)`` (contract item 6 of
:class:`~workbench.plugin.formalism.Formalism`), and is checked against that declaration
rather than failed by construction: ``approximation`` (the declaration is a number > 0);
``dof`` asks for at least describe's DOF (constraint rows turned into forces add
freedoms, none may be lost); ``accelerations`` are not compared on models with
constraints (at a consistent state a penalty force is still zero); ``constraints`` must
stay within the declared residual; ``energy``, ``invariants`` and ``trajectory`` within
:data:`APPROXIMATE_FACTOR` x declared / the model's length scale (a residual of that size
displaces the bodies and stores energy of that relative size), when that is looser than
their own tolerance.
"""

from __future__ import annotations

import math
import time
from collections.abc import Collection
from typing import Any

import numpy as np

from workbench.equations import FORMS, Equations
from workbench.errors import one_line
from workbench.mechanics.forces import is_conservative_model
from workbench.mechanics.kinematics import TreeKinematics, initial_joint_values
from workbench.numerics.geometry import length_scale, pose_error
from workbench.numerics.linalg import independent_rows
from workbench.plugin.formalism import FEATURES, Formalism
from workbench.plugin.registry import get_formalism
from workbench.testing.common import check_structure, problem_instances, resolve_plugin
from workbench.testing.report import ConformanceReport
from workbench.testing.states import (
    body_accelerations,
    central_difference,
    energy_scale,
    formalism_state,
    missing_ode_form,
    observed,
    random_joint_states,
    tight_run,
)

REFERENCES = (
    ("minimal-ode", {"index": 1}),
    ("recursive", {"index": 1}),
    ("absolute-dae", {"index": 1}),
)
"""Reference formalisms: the first that is not the one under test and supports the model."""

TOLERANCES = {
    "observables": 1e-9,  # relative to the largest value
    "accelerations": 1e-8,  # relative to max(1, largest body acceleration)
    "jacobian": 1e-5,  # relative, central differences
    "energy": 1e-7,  # relative to the energy in the motion, over the tight run
    "invariants": 1e-7,
    "constraints": 1e-6,  # absolute residuals (m, rad, m/s)
    "trajectory": 1e-7,  # end pose error / length scale
}

APPROXIMATE_FACTOR = 10.0
"""Motion errors a formalism with approximate constraints may reach: this x its declared
residual over the model's length scale (relative; see the module docstring)."""

GROUPS = {
    "agreement": "observables and accelerations vs a reference formalism at random states",
    "jacobians": "exact Jacobians of every form vs central differences",
    "motion": "energy, invariants, constraint drift and end pose over a short tight run",
}

_REFERENCE_CACHE: dict[tuple[str, str, str], Equations] = {}


def check_formalism(
    formalism: str | type,
    problems: Any = None,
    options: dict[str, Any] | None = None,
    checks: str | Collection[str] = "all",
    n_states: int = 3,
    horizon: float = 0.2,
    seed: int = 0,
) -> Any:
    """Check a formalism (registered name or class); returns a ConformanceReport.

    ``problems``: None (a fast subset, one problem per model feature), "all", or names /
    Problem classes or instances. ``options``: the formalism's options (default ones if
    None). ``checks``: "structural" (no build), "all", or some of :data:`GROUPS`
    ("agreement", "jacobians", "motion"; build and equations are always checked).
    ``n_states`` random consistent states per problem; ``horizon`` s of the tight run
    (the summary says it: a PASS holds over that span only).
    """
    plugin = resolve_plugin("formalism", formalism)
    report = ConformanceReport("formalism", getattr(plugin, "name", plugin.__qualname__))
    defaults = check_structure(report, "formalism", plugin, Formalism)
    parsed = _check_declarations(report, plugin, options, defaults)
    declared = _check_approximation(report, plugin, parsed)
    groups = _groups(checks)
    if not groups or parsed is None or declared is False:
        return report
    if "motion" in groups:  # a formalism may pass these and still fail later in a run
        report.span = horizon
    for problem in problem_instances(problems):
        _check_problem(
            report, plugin, options or {}, problem, groups, (n_states, horizon, seed), declared
        )
    return report


def _check_approximation(report: ConformanceReport, plugin: type, parsed: Any) -> Any:
    """The declared constraint tolerance (None: exact constraints; False: a bad one)."""
    if parsed is None:
        return None
    try:
        declared = plugin.constraint_tolerance(parsed)
    except AttributeError:  # not a Formalism subclass: metadata says so
        return None
    except Exception as error:  # noqa: BLE001
        report.failed(
            "approximation", "", f"constraint_tolerance(options) raised {one_line(error)}"
        )
        return False
    if declared is None:
        return None
    if (
        isinstance(declared, bool)
        or not isinstance(declared, int | float)
        or not (0 < declared < math.inf)
    ):
        report.failed(
            "approximation",
            "",
            f"constraint_tolerance(options) must be None (exact constraints) or a residual "
            f"> 0 (m, rad, m/s), not {declared!r}",
        )
        return False
    report.passed("approximation", message=f"constraints held to {declared:g} (declared)")
    return float(declared)


def _groups(checks: str | Collection[str]) -> set[str]:
    if checks == "structural":
        return set()
    if checks == "all":
        return set(GROUPS)
    chosen = {checks} if isinstance(checks, str) else set(checks)
    unknown = chosen - set(GROUPS)
    if unknown:
        raise ValueError(
            f"unknown check groups {sorted(unknown)}; use 'structural', 'all' or {list(GROUPS)}"
        )
    return chosen


def _check_declarations(
    report: ConformanceReport, plugin: type, options: Any, defaults: Any
) -> Any:
    capabilities = getattr(plugin, "capabilities", None)
    unknown = sorted(set(capabilities or ()) - set(FEATURES))
    if not capabilities or unknown or not {"planar", "spatial"} & set(capabilities):
        why = f"unknown features {unknown}" if unknown else "declare at least planar or spatial"
        report.failed("capabilities", "", f"{why}; features: {', '.join(FEATURES)}")
    else:
        report.passed("capabilities", message=", ".join(sorted(capabilities)))
    if defaults is None:
        return None
    try:
        parsed = plugin.parse_options(options)
        forms = plugin.forms(parsed)
        bad = {k: v for k, v in dict(forms).items() if k not in FORMS or v not in (0, 1, 2, 3)}
        if not forms or bad:
            report.failed(
                "forms",
                "",
                f"forms(options) must map some of {FORMS} to an index 0..3, got {forms!r}",
            )
            return None
        report.passed("forms", message=", ".join(f"{k} ({v})" for k, v in forms.items()))
        return parsed
    except Exception as error:  # noqa: BLE001
        report.failed("forms", "", f"forms(options) raised {one_line(error)}")
        return None


def reference_equations(problem: Any, model: Any, subject: str) -> tuple[str, Equations]:
    """(name, equations) of the first reference formalism that is not ``subject``."""
    name, options = next(
        (n, o) for n, o in REFERENCES if n != subject and not get_formalism(n).unsupported(model)
    )
    key = (name, problem.name, repr(problem.options))
    if key not in _REFERENCE_CACHE:
        _REFERENCE_CACHE[key] = get_formalism(name)().build(model, options)
    return name, _REFERENCE_CACHE[key]


def _relative(a: np.ndarray, b: np.ndarray, floor: float = 1.0) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        return math.inf
    if not a.size:
        return 0.0
    return float(np.max(np.abs(a - b)) / max(floor, float(np.max(np.abs(b)))))


def _check_problem(
    report: ConformanceReport,
    plugin: type,
    options: dict[str, Any],
    problem: Any,
    groups: set[str],
    sampling: tuple[int, float, int],
    declared: float | None,
) -> None:
    n_states, horizon, seed = sampling
    name = problem.name
    model = problem.model()
    missing = plugin.unsupported(model)
    if missing:
        report.skipped(
            "supported",
            name,
            "does not support " + ", ".join(FEATURES.get(f, f) for f in sorted(missing)),
        )
        return
    started = time.perf_counter()
    try:
        equations = plugin().build(model, options)
    except Exception as error:  # noqa: BLE001
        report.failed("build", name, one_line(error))
        return
    report.passed("build", name, f"{time.perf_counter() - started:.2f} s")
    if not _check_equations(report, plugin, options, equations, name):
        return
    _check_dof(report, problem, model, equations, name, declared)
    reference_name, reference = reference_equations(problem, model, plugin.name)
    states = list(random_joint_states(problem, n_states, seed))
    constrained = declared is not None and bool(model.cut_joints or model.nonholonomic)
    if "agreement" in groups:
        _check_agreement(report, name, equations, reference, reference_name, states, constrained)
    state = formalism_state(equations, *states[-1])
    if "jacobians" in groups:
        _check_jacobians(report, equations, state, name)
    if "motion" in groups:
        _check_motion(
            report, problem, model, (equations, reference, reference_name), state, horizon, declared
        )


def _check_dof(
    report: ConformanceReport,
    problem: Any,
    model: Any,
    equations: Equations,
    name: str,
    declared: float | None = None,
) -> None:
    """The equations keep the DOF ``workbench describe`` finds: nv - rank of the
    constraint rows they keep, at the consistent initial state (both decided at the
    problem's initial configuration, which the model carries). With approximate
    constraints (``declared``), at least that many: rows turned into forces add DOF."""
    from workbench.equations.initial import consistent_initial_state
    from workbench.mechanics.topology import analyze

    try:
        expected = analyze(model).dof
        state = consistent_initial_state(equations, problem)
    except Exception as error:  # noqa: BLE001
        report.failed("dof", name, f"at the initial state: {one_line(error)}")
        return
    nv, mechanical = equations.nv, equations.forms.get("mechanical")
    nc = int(mechanical.n_constraints) if mechanical is not None else 0
    rank = 0
    if nc:
        (w_matrix,) = mechanical.velocity_matrix(problem.t_start, state.q)
        rank = len(independent_rows(np.reshape(np.asarray(w_matrix, dtype=float), (nc, nv))))
    dof = nv - rank
    if dof == expected:
        report.passed("dof", name, f"{dof} (as workbench describe)")
    elif declared is not None and dof > expected:
        report.passed(
            "dof",
            name,
            f"{dof} ({nv} velocities, rank {rank} of {nc} constraint rows): approximate "
            f"constraints (declared {declared:g}); workbench describe finds {expected}",
        )
    else:
        report.failed(
            "dof",
            name,
            f"the equations keep {dof} degrees of freedom at the initial state ({nv} "
            f"velocities, rank {rank} of {nc} constraint rows); workbench describe finds "
            f"{expected}: decide the rank at workbench.mechanics.topology.rank_configurations",
        )


def _check_agreement(
    report: ConformanceReport,
    name: str,
    equations: Equations,
    reference: Equations,
    reference_name: str,
    states: list,
    approximate: bool = False,
) -> None:
    """Observables and accelerations against the reference at the same states; with
    ``approximate`` constraints the accelerations are not compared (see the module
    docstring)."""
    worst = {"observables": 0.0, "accelerations": 0.0}
    for t, q_joint, v_joint in states:
        try:
            ours = formalism_state(equations, t, q_joint, v_joint)
        except Exception as error:  # noqa: BLE001
            report.failed("accelerations", name, f"at t = {t:g}: {one_line(error)}")
            return
        theirs = formalism_state(reference, t, q_joint, v_joint)
        a, b = observed(equations, ours), observed(reference, theirs)
        worst["observables"] = max(
            worst["observables"], *(_relative(a[k], b[k]) for k in ("poses", "twists", "energy"))
        )
        acc_a = body_accelerations(equations, ours)
        acc_b = body_accelerations(reference, theirs)
        worst["accelerations"] = max(worst["accelerations"], _relative(acc_a, acc_b))
    against = f"vs {reference_name} at {len(states)} random consistent states"
    report.add("observables", name, worst["observables"], TOLERANCES["observables"], against)
    if approximate:
        report.skipped(
            "accelerations",
            name,
            "approximate constraints (declared): at a consistent state the constraint forces "
            "are not yet acting; the motion checks hold them to the declaration",
        )
    else:
        report.add(
            "accelerations", name, worst["accelerations"], TOLERANCES["accelerations"], against
        )


def _check_equations(
    report: ConformanceReport, plugin: type, options: dict[str, Any], equations: Any, name: str
) -> bool:
    """Sizes, declared forms and observable shapes; False if unusable."""
    problems = []
    if not isinstance(equations, Equations):
        report.failed(
            "equations",
            name,
            f"build returned {type(equations).__name__}, not "
            "workbench.equations.Equations (use build_equations)",
        )
        return False
    model = equations.model
    nq, nv = equations.nq, equations.nv
    declared = set(plugin.forms(plugin.parse_options(options)))
    if not declared <= set(equations.forms):
        problems.append(f"declared forms {sorted(declared)} but built {sorted(equations.forms)}")
    if "ode" in equations.forms and equations.forms["ode"].n != nq + nv:
        problems.append(f"ode form has n = {equations.forms['ode'].n}, not nq + nv = {nq + nv}")
    if "dae" in equations.forms:
        dae = equations.forms["dae"]
        if dae.n < nq + nv or dae.algebraic.size != dae.n:
            problems.append(f"dae form n = {dae.n}, algebraic flags {dae.algebraic.size}")
    obs = equations.observables
    n_bodies = len(model.bodies)
    if list(obs.body_names) != list(model.bodies):
        problems.append(f"observables name bodies {obs.body_names}, model has {list(model.bodies)}")
    t, q, v = 0.0, np.zeros(nq), np.zeros(nv)
    kinematics = TreeKinematics(model)
    q_joint = initial_joint_values(model, kinematics, {}, False)
    try:
        sizes = {
            "frames": [np.size(x) for x in obs.frames(t, q)],
            "twists": [np.size(x) for x in obs.twists(t, q, v)],
            "energy": [np.size(x) for x in obs.energy(t, q, v)],
            "joint_space_map": [
                np.size(x) for x in equations.joint_space_map(t, q_joint, np.zeros(kinematics.nv))
            ],
        }
        expected = {
            "frames": [3 * n_bodies, 9 * n_bodies],
            "twists": [6 * n_bodies],
            "energy": [2],
            "joint_space_map": [nq, nv],
        }
        for key, want in expected.items():
            if sizes[key] != want:
                problems.append(f"{key} has output sizes {sizes[key]}, expected {want}")
        if len(obs.residuals(t, q, v)) != 3:
            problems.append("residuals must return position, velocity, nonholonomic vectors")
    except Exception as error:  # noqa: BLE001
        problems.append(f"observables failed to evaluate: {one_line(error)}")
    if len(equations.q_names) != nq or len(equations.v_names) != nv:
        problems.append("q_names / v_names do not match the sizes")
    if problems:
        report.failed("equations", name, "; ".join(problems))
        return False
    report.passed("equations", name, f"nq = {nq}, nv = {nv}, forms " + ", ".join(equations.forms))
    return True


def _check_jacobians(
    report: ConformanceReport, equations: Equations, state: Any, name: str
) -> None:
    t, q, v = state.t0, state.q, state.v
    y = np.concatenate([q, v])
    tol = TOLERANCES["jacobian"]
    if "ode" in equations.forms:
        ode = equations.forms["ode"]
        exact = np.atleast_2d(ode.jacobian(t, y)[0])
        numeric = central_difference(lambda x: ode.rhs(t, x)[0], y)
        report.add("jacobian-ode", name, _relative(exact, numeric), tol, "df/dy")
    if "dae" in equations.forms:
        dae = equations.forms["dae"]
        y_dae, yp_dae = state.y0(equations, "dae"), state.yp0(equations, "dae")
        c = 0.37
        exact = np.atleast_2d(dae.jacobian(t, y_dae, yp_dae, c)[0])
        numeric = central_difference(lambda x: dae.residual(t, x, yp_dae)[0], y_dae) + c * (
            central_difference(lambda x: dae.residual(t, y_dae, x)[0], yp_dae)
        )
        report.add("jacobian-dae", name, _relative(exact, numeric), tol, "dF/dy + c dF/dy'")
    if "mechanical" in equations.forms:
        mech = equations.forms["mechanical"]
        a, lam = state.acceleration, state.multipliers
        lam = np.resize(lam, mech.n_constraints) if lam.size != mech.n_constraints else lam
        _, r_q, r_v, mass, _ = mech.dynamics(t, q, v, a, lam)

        def residual(q_: np.ndarray, v_: np.ndarray, a_: np.ndarray) -> np.ndarray:
            return mech.dynamics(t, q_, v_, a_, lam)[0]

        error = max(
            _relative(np.atleast_2d(r_q), central_difference(lambda x: residual(x, v, a), q)),
            _relative(np.atleast_2d(r_v), central_difference(lambda x: residual(q, x, a), v)),
            _relative(np.atleast_2d(mass), central_difference(lambda x: residual(q, v, x), a)),
        )
        report.add("jacobian-mechanical", name, error, tol, "dr/dq, dr/dv, M = dr/dv'")


def _check_motion(
    report: ConformanceReport,
    problem: Any,
    model: Any,
    subject: tuple[Equations, Equations, str],
    state: Any,
    horizon: float,
    declared: float | None = None,
) -> None:
    """Energy, invariants, constraint residuals and the end pose over a tight run of the
    ode form; with ``declared`` approximate constraints, held to the declaration."""
    equations, reference, reference_name = subject
    name = problem.name
    t_end = state.t0 + horizon
    if missing_ode_form(equations):  # a form not offered: nothing to check, no finding
        report.skipped("energy", name, missing_ode_form(equations))
        return
    try:
        times, y = tight_run(equations, state, t_end)
    except Exception as error:  # noqa: BLE001 - the formalism's own run failed: a finding
        report.failed("tight-run", name, f"DOP853 rtol 1e-10 over {horizon:g} s: "
                      f"{one_line(error)}; energy, invariants, constraints and the end "
                      "pose not checked")  # fmt: skip
        return
    obs, nq, nv = equations.observables, equations.nq, equations.nv
    energies = np.array(
        [np.ravel(obs.energy(t, r[:nq], r[nq : nq + nv])[0]) for t, r in zip(times, y, strict=True)]
    )
    run = f"over {horizon:g} s, DOP853 rtol 1e-10"
    tolerances = dict(TOLERANCES)
    ref_state = formalism_state(reference, state.t0, state.q_joint, state.v_joint)
    if declared is not None:
        ref_poses = reference.observables.poses(state.t0, ref_state.q)[None]
        relative = APPROXIMATE_FACTOR * declared / length_scale(model, ref_poses)
        for check in ("energy", "invariants", "trajectory"):
            tolerances[check] = max(tolerances[check], relative)
        tolerances["constraints"] = declared
        run += f", approximate constraints declared {declared:g}"
    if problem.conservative and is_conservative_model(model):
        total = energies.sum(axis=1)
        error = float(np.max(np.abs(total - total[0]))) / energy_scale(energies)
        report.add("energy", name, error, tolerances["energy"], run)
    else:
        report.skipped("energy", name, "not a conservative problem")
    if problem.invariants():
        poses = [obs.poses(t, r[:nq]) for t, r in zip(times, y, strict=True)]
        twists = [
            np.reshape(obs.twists(t, r[:nq], r[nq : nq + nv])[0], (6, -1)).T
            for t, r in zip(times, y, strict=True)
        ]
        worst, which = 0.0, ""
        for invariant in problem.invariants():
            values = invariant.along(model, times, np.stack(poses), np.stack(twists))
            scale = abs(values[0]) if abs(values[0]) >= 1e-12 else 1.0
            error = float(np.max(np.abs(values - values[0]))) / scale
            if error >= worst:
                worst, which = error, invariant.name
        report.add("invariants", name, worst, tolerances["invariants"], f"worst: {which}, {run}")
    residuals = [obs.residuals(t, r[:nq], r[nq : nq + nv]) for t, r in zip(times, y, strict=True)]
    sizes = [np.size(x) for x in residuals[0]]
    if sizes[0] or sizes[2]:
        drift = max(
            float(np.max(np.abs(x))) if np.size(x) else 0.0 for row in residuals[1:] for x in row
        )
        report.add(
            "constraints",
            name,
            drift,
            tolerances["constraints"],
            f"largest residual (joints, contacts) {run}",
        )
    try:
        _, y_ref = tight_run(reference, ref_state, t_end)
    except Exception as error:  # noqa: BLE001 - the reference's run, not the subject's
        report.skipped("trajectory", name, f"the reference formalism {reference_name!r}'s "
                       f"run failed: {one_line(error)}")  # fmt: skip
        return
    ours = obs.poses(t_end, y[-1, :nq])[None]
    theirs = reference.observables.poses(t_end, y_ref[-1, : reference.nq])[None]
    length = length_scale(model, theirs)
    error = float(pose_error(ours, theirs, length)[0]) / length
    report.add(
        "trajectory", name, error, tolerances["trajectory"], f"end pose vs {reference_name} {run}"
    )
