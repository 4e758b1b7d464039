"""The health audit: a row that is wrong, or might be, says so (issue: trust).

Each test would pass unnoticed without the audit: the rows below say ``ok``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
import pytest

from workbench.equations.initial import consistent_initial_state
from workbench.execution.execute import RunSpec, execute_run
from workbench.execution.metrics import trajectory_metrics
from workbench.execution.references import ReferencePoses
from workbench.plugin.registry import get_formalism, get_problem


def run(problem, formalism, integrator, rtol, formalism_options=None, problem_options=None):
    spec = RunSpec(problem, formalism, integrator, rtol, rtol * 1e-3,
                   problem_options or {}, formalism_options or {})  # fmt: skip
    return execute_run(spec).row


# A run through a singular configuration that leaves its assembly branch (IFToMM A02):
# tests/test_branch.py, on every path (which rows leave depends on the machine's rounding).


def test_a_clean_run_has_no_warning():
    row = run("slider-crank", "minimal-ode", "scipy-dop853", 1e-8, {"index": 1})
    assert row["status"] == "ok" and row["warnings"] == ""
    assert 0.05 < row["jacobian_sv_ratio_min"] <= 1.0  # W stays far from singular
    assert row["dof_start"] == row["dof_max"] == 1
    assert row["rotation_defect_max"] < 1e-12


def test_a_tolerance_below_float64s_is_judged_at_its_least():
    """rtol 1e-20 asked of an explicit method (SciPy takes 2.2e-14): the rotations and the
    energy are right to rounding (1e-16 a step, 1e-14 after the run), which 100 and 1000
    times 1e-20 would call drift; the audit holds the run to 100 machine epsilons instead,
    and still warns a defect beyond that, saying which rtol it judged."""
    from workbench.execution.audit import LEAST_RTOL, audit_warnings

    row = run("double-pendulum", "recursive", "scipy-dop853", 1e-20)
    assert row["status"] == "ok"
    assert row["energy_err_max"] < 1e-11  # rounding only: an exact invariant
    assert "rotations off" not in row["warnings"] and "energy" not in row["warnings"]
    assert "SciPy raises rtol 1e-20" in row["warnings"]  # the integrator's own word
    metrics = {"energy_err_max": 1e-10}
    (energy,) = audit_warnings({"rotation_defect_max": 1e-15}, metrics, 1e-20, True)
    assert energy.startswith("energy not conserved") and f"taken as {LEAST_RTOL:.2g}" in energy
    assert audit_warnings({"rotation_defect_max": 1e-11}, {}, 1e-20, False)[0].startswith(
        "rotations off the unit sphere"
    )
    assert not audit_warnings({"rotation_defect_max": 1e-13}, {}, 1e-8, False)


def test_euler_parameters_off_the_unit_sphere_are_seen():
    """The observables orthonormalize rotations for the poses (and the formalisms build
    rotations of p / |p|), so a run whose Euler parameters drift off the unit sphere shows
    no pose error. Scaling the heavy top's quaternion by 1 + delta shows as |p^T p - 1| of
    about 2 delta, and the row is warned; through every formalism that has them."""
    problem = get_problem("heavy-top")()
    equations = get_formalism("minimal-ode")().build(problem.model(), {})
    state = consistent_initial_state(equations, problem)
    times = problem.sample_times()[:3]
    y = np.tile(np.concatenate([state.q, state.v]), (3, 1))
    delta = 1e-3
    y[1:, :4] *= 1 + delta  # the spherical joint's Euler parameters
    reference = ReferencePoses("analytic", None, "none here")
    row, _ = trajectory_metrics("x", problem, equations, times, y, True, reference, 1e-8)
    assert 1.9 * delta < row["rotation_defect_max"] < 2.2 * delta
    assert "rotations off the unit sphere" in row["warnings"]
    for formalism, options in [("absolute-dae", {"index": 1}), ("recursive", {}),
                               ("nonholonomic-projection", {})]:  # fmt: skip
        other = get_formalism(formalism)().build(problem.model(), options)
        assert len(other.quaternion_slices) == 1, formalism
        part = other.quaternion_slices[0]
        start = consistent_initial_state(other, problem)
        y = np.tile(np.concatenate([start.q, start.v]), (3, 1))
        y[1:, part] *= 1 + delta
        row, _ = trajectory_metrics("x", problem, other, times, y, True, reference, 1e-8)
        assert 1.9 * delta < row["rotation_defect_max"] < 2.2 * delta, formalism


def test_more_digits_than_the_reference_has_are_not_credited():
    """The simple pendulum's stored reference states 1e-15 of L (heyoka in extended
    precision; the round-off floor): the same method at tol 1e-18 ends closer to it than
    that. Its scd is capped at what the reference supports, and the row says so."""
    spec = RunSpec("simple-pendulum", "recursive", "heyoka-taylor", 1e-18, 1e-18,
                   integrator_options={"precision": "extended"})  # fmt: skip
    row = execute_run(spec).row
    accuracy = row["reference_accuracy"]
    assert row["reference_kind"] == "stored" and 1e-16 < accuracy <= 1e-14
    assert row["err_end"] / row["length_scale"] < accuracy
    assert row["scd"] == pytest.approx(-math.log10(accuracy))
    assert "below the reference's own accuracy" in row["warnings"]


def test_warnings_are_one_line_and_listed_in_the_schema():
    from workbench.execution import row_schema

    row = run("iftomm-a02", "minimal-ode", "sundials-cvode-bdf", 1e-4, {"index": 1})
    assert "\n" not in row["warnings"]
    for column in ("warnings", "jacobian_sv_ratio_min", "branch_left_at", "branch_distance_max",
                   "dof_start", "dof_max",
                   "rotation_defect_max", "reference_accuracy"):  # fmt: skip
        assert column in row_schema.SCHEMA_COLUMNS and column in row


def test_each_warning_is_one_item_of_the_list():
    """'; ' separates warnings: no warning may contain it (the report counts their kinds)."""
    from workbench.execution.audit import audit_warnings

    audit = {"jacobian_sv_ratio_min": 1e-9, "jacobian_sv_ratio_at": 1.0, "dof_start": 1,
             "dof_max": 3, "rotation_defect_max": 1.0,
             "formalism_notes": "removed redundant constraint rows: a; b"}  # fmt: skip
    metrics = {"energy_err_max": 1.0, "err_end": 1e-14, "length_scale": 1.0}
    found = audit_warnings(audit | {"reference_accuracy": 1e-10}, metrics, 1e-8, True)
    assert len(found) == 6 and all("; " not in w for w in found)


def _one_sample_at_a_time(function, n, args, cache):
    """evaluate_along's contract met by n separate calls (what the audit did before)."""
    outputs = [function.call([np.asarray(a)[:, k] for a in args]) for k in range(n)]
    return [np.stack([np.array(out[i]) for out in outputs]) for i in range(function.n_out())]


@pytest.mark.parametrize(
    ("problem", "formalism", "options"),
    [
        ("four-bar", "absolute-dae", {"index": 1}),  # W of the formalism's constraint rows
        ("iftomm-a02", "nonholonomic-projection", {}),  # loops eliminated: residual Jacobian
        ("ball-on-rotating-plane", "nonholonomic-projection", {}),  # velocity partition W_d
    ],
)
def test_the_audit_of_all_samples_at_once_equals_one_sample_at_a_time(
    problem, formalism, options, monkeypatch
):
    """The audit evaluates W (or W_d, or the residual Jacobian) at every output time in one
    mapped call; its columns are bit for bit those of one call per sample, on perturbed
    states whose ratio has local minima (so the refinement runs too)."""
    from workbench.execution import audit

    problem_ = get_problem(problem)()
    equations = get_formalism(formalism)().build(problem_.model(), options)
    state = consistent_initial_state(equations, problem_)
    rng = np.random.default_rng(11)
    n = 40
    times = np.linspace(0.0, 1.0, n)
    nq, nv = equations.nq, equations.nv
    y = np.concatenate([state.q, state.v]) + 0.2 * rng.standard_normal((n, nq + nv))
    rotations = equations.observables.along(times, y[:, :nq], y[:, nq : nq + nv]).rotations
    seen = []  # the ratio at every sample, as the audit hands it to _local_minima

    def local_minima(ratios):
        seen.append(np.array(ratios))
        return minima(ratios)

    minima = audit._local_minima
    monkeypatch.setattr(audit, "_local_minima", local_minima)
    at_once = audit.health_audit(equations, times, y, rotations, 1e-6)
    monkeypatch.setattr(audit, "evaluate_along", _one_sample_at_a_time)
    if getattr(equations, "partition_matrices", None) is not None:  # the per-sample ratios
        function = equations.partition_matrices
        monkeypatch.setattr(equations, "partition_matrices", lambda t, q: function(t, q))
    one_by_one = audit.health_audit(equations, times, y, rotations, 1e-6)
    assert len(seen) == 2 and seen[0].shape == (n,)
    np.testing.assert_array_equal(seen[0], seen[1])
    assert math.isfinite(at_once["jacobian_sv_ratio_min"])
    assert at_once.keys() == one_by_one.keys()
    for key, value in at_once.items():
        same_nan = isinstance(value, float) and math.isnan(value) and math.isnan(one_by_one[key])
        assert value == one_by_one[key] or same_nan, key


@pytest.mark.parametrize(("kind", "warned"), [("analytic", False), ("stored", True)])
def test_an_error_below_the_references_accuracy_warns_only_for_a_computed_one(kind, warned):
    """The same end error (3e-14 of L) below the same stated accuracy (1e-13): a computed
    reference beaten is suspicious (a warning); an analytic one's accuracy is its round-off,
    which an exact method reaches (a note, the fact kept, no warning)."""
    from workbench.execution.audit import at_reference_accuracy, audit_warnings

    metrics = {"err_end": 3e-14, "length_scale": 1.0, "reference_kind": kind}
    found = audit_warnings({"reference_accuracy": 1e-13}, metrics, 1e-7, False)
    note = at_reference_accuracy(metrics, 1e-13)
    assert any("below the reference's own accuracy" in w for w in found) == warned
    assert (note is not None and "3.0e-14 is at the analytic reference's accuracy 1.0e-13"
            in note) != warned  # fmt: skip
    above = at_reference_accuracy(metrics | {"err_end": 1e-12}, 1e-13)
    assert above is None


def test_exact_event_driven_runs_stay_in_the_decision_table():
    """Event-driven on the incline is exact (a constant acceleration): its end error lies
    below the analytic reference's 1e-13. The row is ok without warnings, says so in its
    notes, caps its scd at 13, and is a trusted candidate of the decision table."""
    from workbench.outputs.report.overview import trusted

    row = execute_run(RunSpec("incline-block-stop", "minimal-ode", "event-driven", 1e-7,
                              1e-10)).row  # fmt: skip
    assert row["status"] == "ok" and row["warnings"] == "", row["warnings"]
    assert row["err_end"] / row["length_scale"] < row["reference_accuracy"] == 1e-13
    assert "at the analytic reference's accuracy" in row["notes"]
    assert row["scd"] == pytest.approx(13.0)
    runs = pd.DataFrame([row | {"wall_s": 0.01}])
    assert len(trusted(runs)) == 1


def test_energy_warning_names_a_drive_of_a_problem_declared_conservative():
    """A pendulum on a support shaken as x = 0.1 sin 3t, declared conservative: the
    support's work changes T + V by about 10 % in 5 s, which no method can help; the
    warning says the model has a drive instead of blaming the run alone. Held still, the
    same drive does no work: the energy is measured and conserved, no warning."""
    import casadi as ca

    import workbench
    from workbench.model import Drive, Model
    from workbench.plugin.problem import Problem

    class ShakenPendulum(Problem):
        """A rod (1 kg, 1 m) hanging from a support driven along x (tests)."""

        name = "shaken-pendulum-declared-conservative"
        summary = "rod on a horizontally shaken support, declared conservative"
        source = "tests"
        t_end, n_samples, conservative = 5.0, 101, True

        @dataclass(frozen=True)
        class Options:
            amplitude: float = 0.1  # m

        def model(self):
            a = self.options.amplitude
            model = Model(self.name, kind="planar")
            model.add_body("support", 0.5, inertia=0.01)
            model.add_body("rod", 1.0, com=(0.5, 0.0, 0.0), inertia=1.0 / 12)
            drive = Drive(lambda t: a * ca.sin(3 * t), lambda t: 3 * a * ca.cos(3 * t),
                          lambda t: -9 * a * ca.sin(3 * t))
            model.add_joint("shake", "prismatic", "ground", "support", axis=(1, 0, 0),
                            drive=drive)
            model.add_joint("pivot", "revolute", "support", "rod")
            return model

        def initial_joint_coordinates(self):
            return {"pivot": -math.pi / 2 + 0.3}

    shaken = workbench.run(ShakenPendulum, "minimal-ode", "scipy-dop853", rtol=1e-8).row
    assert shaken["energy_err_max"] > 1e-2  # the support's work, not the method's error
    assert "energy not conserved" in shaken["warnings"]
    assert "declared conservative, has a drive" in shaken["warnings"]
    still = workbench.run(ShakenPendulum, "minimal-ode", "scipy-dop853", rtol=1e-8,
                          amplitude=0.0).row
    assert still["energy_err_max"] < 1e-6 and still["warnings"] == ""
