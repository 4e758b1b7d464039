"""What a run can tell about its own trustworthiness: the health audit of a result row.

A run whose metrics look fine can still be wrong: it may have crossed a singular
configuration and gone on along another assembly branch, its Euler parameters may have
left the unit sphere (the observables orthonormalize rotations, which hides that), the
formalism may have removed constraint rows, or the reference may be less accurate than
the run. :func:`health_audit` measures these at the run's output times and turns each
into a warning, so that ``ok`` without warnings means the workbench saw nothing wrong.

Columns (:data:`AUDIT_COLUMNS`):

- ``jacobian_sv_ratio_min``: the smallest sigma_min / sigma_max of the formalism's
  constraint Jacobian W(t, q) (rows of the mechanical form), over the output times and,
  around each sampled local minimum, over a cubic Hermite interpolant of q between output
  times (a singular configuration is crossed between samples); ``jacobian_sv_ratio_at``
  its time. For a formalism whose equations keep no constraint rows but solve a fixed
  block W_d of W for dependent velocities (``Equations.partition_matrices``, a note
  beginning with PARTITION_NOTE): sigma_min(W_d) / sigma_max(W) instead, found the same
  way, each sample in the partition it was computed in when the run changed partition
  (``Equations.atlas``, :mod:`workbench.execution.charts`). NaN without constraints.
- ``dof_start``, ``dof_max``: nv - rank W at the start and the most along the output
  times (rank by :func:`workbench.numerics.linalg.independent_rows`, the algorithm every
  formalism and ``describe`` use).
- ``rotation_defect_max``: how far from rotations the run's orientations are: the largest
  |R^T R - I| (entry) of the body rotation matrices the formalism produces, and the largest
  |p^T p - 1| of the Euler parameters among its coordinates (``Equations.quaternion_slices``;
  about 2 delta off the unit sphere by delta; the rotations built from them are normalized,
  so only their norm shows the drift).
- ``formalism_notes``: the formalism's own notes (``Equations.notes``).
- ``reference_accuracy``: the relative accuracy the reference states for itself.

- ``branch_left_at``: the first output time at which the run is off the assembly branch
  it started on (:mod:`workbench.execution.branch`: the branch followed by continuation, not a
  threshold on sampled singular values, so it does not depend on where the samples fall);
  NaN when it stays on it. ``branch_distance_max``: the distance from that branch there
  (or the largest along a run that stays); NaN both when the branch was not followed (no
  position constraints, or the coordinates changed chart).

Warnings (column ``warnings``, "; "-separated, one line): a run whose state never moved
(:func:`motionless_warning`); a run that left its assembly
branch; a singular passage (ratio below SINGULAR_RATIO) only where the branch could not
be followed (a passage alone is no error: the exact motion of IFToMM A02 passes through
singular points); for a fixed velocity partition, a singular partition; a change of DOF
along the run, a rotation defect beyond ROTATION_FACTOR
times rtol, constraint rows removed by the formalism (a note that begins "removed"), an
energy error beyond ENERGY_FACTOR times rtol for a conservative problem, and an end error
below a computed reference's accuracy (the scd is then capped at what the reference
supports). Below an analytic reference's accuracy (its round-off) the scd is capped the
same way but the row gets a note, not a warning (:func:`at_reference_accuracy`): an exact
method reaches it, and the run stays in the report's decision table. An rtol below
LEAST_RTOL gets a note too (:func:`below_least_rtol`).
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np
from scipy.optimize import minimize_scalar

from workbench.equations.evaluate import FastFunction, evaluate_along
from workbench.execution.branch import branch_departure, constraints_of
from workbench.numerics.linalg import extreme_singular_values, independent_rows

SINGULAR_RATIO = 1e-4  # sigma_min / sigma_max of W below this: a singular passage
PARTITION_NOTE = "fixed velocity partition"  # how a formalism's notes declare one
MEASURE = "_measured_on"  # audit key (not a column): "partition" when W_d was measured
ROTATION_FACTOR = 100.0  # rotation defect beyond this times rtol: a warning
ENERGY_FACTOR = 1e3  # relative energy error beyond this times rtol: a warning
LEAST_RTOL = 100 * np.finfo(float).eps
"""The least tolerance the audit judges against: a run asked for less (rtol 1e-20) is
held to this, as SciPy and scipy-dae raise it (float64's rounding alone, 1e-16 a
step, reaches 100 x 1e-20); its row says which rtol was judged."""
REFINE_EVALUATIONS = 40  # Hermite-interpolated evaluations of W around each sampled minimum
REFINE_MOST = 5  # sampled local minima refined, the deepest first
REFINE_BELOW = 0.5  # ... and only those below this fraction of the median ratio

AUDIT_COLUMNS = [
    "warnings",
    "jacobian_sv_ratio_min",
    "jacobian_sv_ratio_at",
    "branch_left_at",
    "branch_distance_max",
    "dof_start",
    "dof_max",
    "rotation_defect_max",
    "formalism_notes",
    "reference_accuracy",
]


def health_audit(
    equations: Any,
    times: np.ndarray,
    y: np.ndarray,
    rotations: np.ndarray,
    rtol: float,
    charts: list[Any] | None = None,
) -> dict[str, Any]:
    """The audit columns of a run (no warnings yet: see :func:`audit_warnings`).

    times (n,), y (n, >= nq + nv) in the layout [q, v, ...], rotations (n, n_bodies, 3, 3)
    as the observables give them (not orthonormalized). ``charts``: each sample's chart
    when the run changed chart (``Equations.atlas``): its partition is measured there.
    """
    nq, nv = equations.nq, equations.nv
    q, v = y[:, :nq], y[:, nq : nq + nv]
    row: dict[str, Any] = {
        "jacobian_sv_ratio_min": math.nan,
        "jacobian_sv_ratio_at": math.nan,
        "dof_start": math.nan,
        "dof_max": math.nan,
        "rotation_defect_max": max(
            _rotation_defect(rotations), _euler_parameter_defect(equations, q)
        ),
        "formalism_notes": "; ".join(" ".join(str(n).split()) for n in equations.notes),
    }
    row.update(_branch_columns(equations, times, q, charts))
    mechanical = equations.forms.get("mechanical")
    if mechanical is None or len(times) == 0:
        return row
    nc = int(mechanical.n_constraints)
    if nc:
        width = nv

        def jacobian(t: float, q_t: np.ndarray) -> np.ndarray:
            (w,) = mechanical.velocity_matrix(t, q_t)
            return np.reshape(np.asarray(w, dtype=float), (nc, nv))

        matrices = _velocity_matrices(equations, mechanical.velocity_matrix, times, q)
        if matrices is None:  # compiled C: evaluated where the integrator evaluates it
            matrices = np.stack([jacobian(t, q_k) for t, q_k in zip(times, q, strict=True)])
    elif equations.model.cut_joints:
        # closed loops eliminated by the formalism (minimal velocities): the loops can still
        # pass a singular configuration, seen in the Jacobian of every joint's residual on
        # the body poses (observables), with respect to the formalism's q
        width, jacobian = nq, _residual_jacobian(equations)
        function = equations.observables._audit_jacobian
        zeros = np.zeros((equations.nv, len(times)))
        (matrices,) = evaluate_along(function, len(times), [times[None], q.T, zeros],
                                     _mapped(equations))  # fmt: skip
    else:
        row["dof_start"] = row["dof_max"] = nv
        if getattr(equations, "partition_matrices", None) is not None:
            atlas = getattr(equations, "atlas", None)
            in_chart = (
                [atlas.equations(c) for c in charts[: len(times)]]
                if charts and atlas is not None
                else [equations] * len(times)
            )
            row.update(_partition_audit(in_chart, times, q, v))
            row[MEASURE] = "partition"
        return row

    dof_start = width - len(independent_rows(matrices[0]))
    rank = width - dof_start  # rows redundant at the start are not a passage
    if rank <= 0:
        row["dof_start"] = row["dof_max"] = dof_start
        return row
    values = extreme_singular_values(matrices, rank)  # (n, 2): sigma_1, sigma_rank
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = np.where(values[:, 0] > 0, values[:, 1] / values[:, 0], 0.0)
    # the least ratio and its time as the SVD's: those within the eigenvalues' rounding
    # of the least (the ratio may stay the same along a run) taken again by the SVD
    close = np.flatnonzero(ratios <= np.min(ratios) * (1 + 1e-9))
    exact = np.linalg.svd(matrices[close], compute_uv=False)
    ratios[close] = np.where(exact[:, 0] > 0, exact[:, rank - 1] / exact[:, 0], 0.0)
    least = int(close[np.argmin(ratios[close])])
    best, best_at = float(ratios[least]), float(times[least])
    deepest = sorted(_local_minima(ratios), key=lambda k: ratios[k])[:REFINE_MOST]
    for k in [k for k in deepest if ratios[k] < REFINE_BELOW * np.median(ratios)]:
        ratio, at = _refine(
            lambda t, q_t: _singular_value_ratio(jacobian(t, q_t), rank),
            lambda j: mechanical.qdot(times[j], q[j], v[j])[0], times, q, k,
        )  # fmt: skip
        if ratio < best:
            best, best_at = ratio, at
    # the rank can only have dropped where W came close to singular
    near = np.flatnonzero(ratios < SINGULAR_RATIO)
    dof_max = max([dof_start] + [width - len(independent_rows(matrices[k])) for k in near])
    if not nc:  # the formalism's velocities are independent by construction
        dof_start = dof_max = nv
    row.update(
        jacobian_sv_ratio_min=best,
        jacobian_sv_ratio_at=best_at,
        dof_start=dof_start,
        dof_max=dof_max,
    )
    return row


def audit_warnings(audit: dict[str, Any], metrics: dict[str, Any], rtol: float,
                   conservative: bool, energy_cause: str = "") -> list[str]:  # fmt: skip
    """The warnings of a row from its audit columns and metrics (see the module); rtol
    below :data:`LEAST_RTOL` is judged as that. ``energy_cause``: what in the model may
    change the energy of a problem declared conservative, said after "energy not
    conserved"."""
    found = []
    floor = f", rtol {rtol:g} taken as {LEAST_RTOL:.2g}" if rtol < LEAST_RTOL else ""
    rtol = max(rtol, LEAST_RTOL)
    ratio, at = audit.get("jacobian_sv_ratio_min", math.nan), audit.get("jacobian_sv_ratio_at")
    partition = audit.get(MEASURE) == "partition"  # what the ratio was measured on
    if ratio < SINGULAR_RATIO and partition:
        found.append(
            f"singular velocity partition: the block W_d of the constraints solved for the "
            f"dependent velocities lost rank near t = {at:.4g} s (sigma_min(W_d)/sigma_max(W) "
            f"{ratio:.1e}); the formalism keeps one partition for the run, digits are lost there"
        )
    elif math.isfinite(audit.get("branch_left_at", math.nan)):
        found.append(
            f"left its assembly branch at a singular configuration: at t = "
            f"{audit['branch_left_at']:.4g} s the configuration is "
            f"{audit.get('branch_distance_max', math.nan):.2g} away from the branch it started "
            f"on (followed by continuation), the run may follow another mechanism's motion"
        )
    elif ratio < SINGULAR_RATIO and not math.isfinite(audit.get("branch_distance_max", math.nan)):
        found.append(
            f"singular passage: the constraint Jacobian lost rank near t = {at:.4g} s "
            f"(sigma_min/sigma_max {ratio:.1e}), the run may have changed assembly branch"
        )
    start, most = audit.get("dof_start", math.nan), audit.get("dof_max", math.nan)
    if most > start:
        found.append(f"degrees of freedom changed along the run: {start} at the start, "
                     f"up to {most}")  # fmt: skip
    defect = audit.get("rotation_defect_max", math.nan)
    if defect > ROTATION_FACTOR * rtol:
        found.append(
            f"rotations off the unit sphere: |R^T R - I| or |p^T p - 1| reached {defect:.2g} "
            f"(> {ROTATION_FACTOR:g} rtol{floor}): the rotation matrices are not orthonormal "
            f"or the Euler parameters drifted from unit norm"
        )
    for note in audit.get("formalism_notes", "").split("; "):
        if note.lower().startswith("removed"):
            found.append(f"the formalism {note}")
    energy = metrics.get("energy_err_max", math.nan)
    if conservative and energy > ENERGY_FACTOR * rtol:
        found.append(f"energy not conserved: relative error {energy:.2g} "
                     f"(> {ENERGY_FACTOR:g} rtol{floor})"
                     + (f": {energy_cause}" if energy_cause else ""))  # fmt: skip
    accuracy = audit.get("reference_accuracy", math.nan)
    relative_end = metrics.get("err_end", math.nan) / metrics.get("length_scale", math.nan)
    if relative_end < accuracy and metrics.get("reference_kind") != "analytic":
        found.append(
            f"end error {relative_end:.1e} is below the reference's own accuracy "
            f"{accuracy:.1e}: scd capped at {-math.log10(accuracy):.2f}"
        )
    return [" ".join(w.replace(";", ",").split()) for w in found]  # "; " separates them


STILL = 1e-12  # no state moved by more than this times max(1, |y(0)|): nothing moved


def motionless_warning(y: np.ndarray) -> str | None:
    """The warning of a run whose states (rows of ``y``, two or more) never left their
    initial values: an equilibrium (a robot at rest in its neutral pose, by default), where
    every error is 0 and every pair looks perfect, which says nothing of the methods."""
    if len(y) < 2 or not np.isfinite(y).all():
        return None
    if np.abs(y - y[0]).max() > STILL * max(1.0, float(np.abs(y[0]).max())):
        return None
    return (
        "nothing moved: the state stayed at its initial value (an equilibrium), so errors, "
        "energy and drift are 0 whatever the method; start it elsewhere (options q0 / v0)"
    )


def at_reference_accuracy(metrics: dict[str, Any], accuracy: float) -> str | None:
    """The row's note when its end error lies below an *analytic* reference's accuracy
    (its evaluation's round-off): the error is resolved only to that accuracy, which an
    exact method (events located on a constant acceleration) reaches; nothing suspicious, so
    a note, not a warning (a computed reference beaten is a warning: audit_warnings)."""
    relative_end = metrics.get("err_end", math.nan) / metrics.get("length_scale", math.nan)
    if metrics.get("reference_kind") != "analytic" or not relative_end < accuracy:
        return None
    return (
        f"end error {relative_end:.1e} is at the analytic reference's accuracy {accuracy:.1e} "
        f"(not resolved below it): scd capped at {-math.log10(accuracy):.2f}"
    )


def below_least_rtol(rtol: float) -> str | None:
    """The row's note when ``rtol`` is below :data:`LEAST_RTOL`, the same for every
    integrator. Float64 rounding (1e-16 a step, accumulated over thousands of steps)
    bounds what any integrator can honour there. Judged on the rtol, not on the error: a
    global error above a local tolerance is no fault (CVODE BDF on the simple pendulum
    ends 5.4e-10 off at rtol 1e-12 and 1.1e-11 off at 1e-14). A note, not a warning: the
    row's error is measured against the reference like any other, the report recommends
    on that measured error, and an accurate run should not be dropped for having been
    asked too much; the note stops a reader taking the rtol for the accuracy. (SciPy,
    which silently runs LEAST_RTOL instead, adds its own warning: that row's rtol names
    an integration that was not done.)"""
    if not rtol < LEAST_RTOL:
        return None
    return (
        f"rtol {rtol:g} is below 100 machine epsilons ({LEAST_RTOL:.2g}), where float64 "
        f"rounding limits what an integrator can honour: the measured error, not the rtol, "
        f"says what was reached"
    )


def _branch_columns(equations: Any, times: np.ndarray, q: np.ndarray,
                     charts: list[Any] | None) -> dict[str, float]:  # fmt: skip
    """``branch_left_at`` and ``branch_distance_max`` (:mod:`workbench.execution.branch`): NaN
    both when not followed (no position constraints; coordinates changed chart)."""
    constraints = constraints_of(equations)
    if constraints is None or (charts and len({id(c) for c in charts[: len(times)]}) > 1):
        return {"branch_left_at": math.nan, "branch_distance_max": math.nan}
    try:
        left_at, distance = branch_departure(constraints, np.asarray(times, dtype=float), q)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):  # not decided
        left_at = distance = math.nan
    return {"branch_left_at": left_at, "branch_distance_max": distance}


def _singular_value_ratio(matrix: np.ndarray, rank: int) -> float:
    """sigma_rank / sigma_1: the smallest singular value of the part of W that had full
    rank at the start (rows redundant from the start stay out of it)."""
    if rank <= 0:
        return math.nan
    values = np.linalg.svd(matrix, compute_uv=False)
    return float(values[rank - 1] / values[0]) if values[0] > 0 else 0.0


def _local_minima(values: np.ndarray) -> list[int]:
    """Indices of the interior local minima of ``values`` (sampled)."""
    k = np.arange(1, values.size - 1)
    return [int(i) for i in k[(values[k] <= values[k - 1]) & (values[k] <= values[k + 1])]]


def _partition_audit(in_chart: list[Any], times: np.ndarray, q: np.ndarray,
                     v: np.ndarray) -> dict[str, Any]:  # fmt: skip
    """For a formalism with a velocity partition (no constraint rows left in its
    equations): the least sigma_min(W_d) / sigma_max(W) along the run and its time, in
    the columns of W's own ratio (``jacobian_sv_ratio_min``, ``..._at``). ``in_chart[k]``:
    the equations (the partition) sample k was computed in."""

    def ratio_in(equations: Any) -> Any:
        matrices = _partition_function(equations)

        def ratio(t: float, q_t: np.ndarray) -> float:
            w_d, w = (np.atleast_2d(np.asarray(x, dtype=float)) for x in matrices(t, q_t))
            scale = np.linalg.norm(w, 2)
            return float(np.linalg.svd(w_d, compute_uv=False)[-1] / scale) if scale > 0 else 0.0

        return ratio

    def rate(j: int) -> np.ndarray:
        return in_chart[j].forms["mechanical"].qdot(times[j], q[j], v[j])[0]

    ratios = np.empty(len(times))
    for equations in {id(e): e for e in in_chart}.values():  # each partition's samples
        rows = np.array([k for k, e in enumerate(in_chart) if e is equations], dtype=int)
        function = equations.partition_matrices
        if isinstance(function, ca.Function):  # all its samples in one mapped call
            w_d, w = evaluate_along(function, rows.size, [times[rows][None], q[rows].T],
                                    _mapped(equations))  # fmt: skip
            scale = np.linalg.norm(w, 2, axis=(1, 2))
            smallest = np.linalg.svd(w_d, compute_uv=False)[:, -1]
            with np.errstate(divide="ignore", invalid="ignore"):
                ratios[rows] = np.where(scale > 0, smallest / scale, 0.0)
        else:
            ratio = ratio_in(equations)
            ratios[rows] = [ratio(times[k], q[k]) for k in rows]
    best, best_at = float(np.min(ratios)), float(times[int(np.argmin(ratios))])
    deepest = sorted(_local_minima(ratios), key=lambda k: ratios[k])[:REFINE_MOST]
    for k in [k for k in deepest if ratios[k] < REFINE_BELOW * np.median(ratios)]:
        value, at = _refine(ratio_in(in_chart[k]), rate, times, q, k)
        if value < best:
            best, best_at = value, at
    return {"jacobian_sv_ratio_min": best, "jacobian_sv_ratio_at": best_at}


def _refine(ratio: Any, rate: Any, times: np.ndarray, q: np.ndarray,
            k: int) -> tuple[float, float]:  # fmt: skip
    """The smallest ``ratio(t, q)`` around sample k (a singular-value ratio), on the cubic
    Hermite interpolant of q (through q and q' = rate(j) = H v + f at the neighbouring
    samples j)."""
    rates = [np.ravel(rate(j)).copy() for j in (k - 1, k, k + 1)]

    def q_at(t: float) -> np.ndarray:
        j = k - 1 if t <= times[k] else k
        t0, t1 = times[j], times[j + 1]
        h, s = t1 - t0, (t - t0) / (t1 - t0)
        r0, r1 = rates[j - (k - 1)], rates[j - (k - 1) + 1]
        return (
            (2 * s**3 - 3 * s**2 + 1) * q[j] + (s**3 - 2 * s**2 + s) * h * r0
            + (-2 * s**3 + 3 * s**2) * q[j + 1] + (s**3 - s**2) * h * r1
        )  # fmt: skip

    result = minimize_scalar(
        lambda t: ratio(t, q_at(t)),
        bounds=(times[k - 1], times[k + 1]),
        method="bounded",
        options={"maxiter": REFINE_EVALUATIONS, "xatol": 1e-9 * max(1.0, abs(times[k]))},
    )
    return float(result.fun), float(result.x)


def _residual_jacobian(equations: Any) -> Any:
    """(t, q) -> d(position residuals of every joint)/dq, made once per equations."""
    observables = equations.observables
    made = getattr(observables, "_audit_jacobian", None)
    if made is None:
        function = observables.residuals.function
        names_in, names_out = function.name_in(), function.name_out()
        made = function.factory(
            "residual_jacobian", list(names_in), [f"jac:{names_out[0]}:{names_in[1]}"]
        )
        observables._audit_jacobian = made
    zero_v = np.zeros(equations.nv)
    return lambda t, q_t: np.asarray(made(t, q_t, zero_v), dtype=float)


def _mapped(equations: Any) -> dict:
    """Where the audit keeps the mapped Functions of ``equations``
    (:func:`~workbench.equations.evaluate.evaluate_along`): made once per equations."""
    return equations.__dict__.setdefault("_audit_mapped", {})


def _velocity_matrices(equations: Any, velocity_matrix: Any, times: np.ndarray,
                       q: np.ndarray) -> np.ndarray | None:  # fmt: skip
    """W(t, q) (n, nc, nv) at every sample in one mapped call of the symbolic Function, or
    None when the formalism's W runs compiled C (then each sample is evaluated by it, the
    values the integrator saw)."""
    evaluated = getattr(velocity_matrix, "evaluated", None)
    if evaluated is not None and evaluated is not velocity_matrix.function:
        return None
    (matrices,) = evaluate_along(velocity_matrix.function, len(times), [times[None], q.T],
                                 _mapped(equations))  # fmt: skip
    return matrices


def _partition_function(equations: Any) -> Any:
    """``equations.partition_matrices`` for one (t, q) at a time: through preallocated
    buffers when it is a CasADi Function with dense outputs (the same evaluation, without
    ``Function.__call__``'s conversions: the refinement calls it up to 200 times a run)."""
    function = equations.partition_matrices
    if not isinstance(function, ca.Function):
        return function
    cache = _mapped(equations)
    if "partition" not in cache:
        try:
            cache["partition"] = FastFunction(function)
        except ValueError:  # sparse outputs
            cache["partition"] = function
    return cache["partition"]


def _euler_parameter_defect(equations: Any, q: np.ndarray) -> float:
    """The largest |p^T p - 1| of the Euler parameters in q (n, nq); 0 without any."""
    slices = getattr(equations, "quaternion_slices", [])
    if not slices or q.size == 0:
        return 0.0
    return max(float(np.max(np.abs(np.sum(q[:, part] ** 2, axis=1) - 1))) for part in slices)


def _rotation_defect(rotations: np.ndarray) -> float:
    if rotations.size == 0:
        return math.nan
    product = np.einsum("...ji,...jk->...ik", rotations, rotations)
    return float(np.max(np.abs(product - np.eye(3))))
