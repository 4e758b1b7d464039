"""What a problem is like, for the report's "why": its family and traits from its model
(closed loops, nonholonomic rows, driven joints, rotations that need quaternions, robot
geometry) and its stiffness from the integrators' own statistics, and which families of
pairs won.

The model comes from the problem's plugin (the registry) and the problem options of its
rows; a problem whose plugin is not installed has only the traits its rows show.
Stiffness is measured, not declared: on a stiff problem explicit integrators (those that
evaluate no Jacobian) need many more steps than implicit ones at the same tolerance, or
reject many of them, or do not finish.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from workbench.outputs.report.analysis import ok_runs, warned

STIFF_STEP_RATIO = 5.0  # explicit / implicit accepted steps at one tolerance
STIFF_REJECTED = 0.3  # rejected / accepted steps of the explicit integrators

# family, in the order the decision table shows them
FAMILIES: tuple[str, ...] = (
    "open trees and chains",
    "rotations (spherical and free joints)",
    "closed loops",
    "nonholonomic",
    "robots (imported geometry)",
    "other",
)


@dataclass
class Traits:
    """A problem's family and traits; ``model`` None when its plugin could not build it."""

    family: str = "other"
    traits: list[str] = field(default_factory=list)
    stiffness: str = ""
    model: Any = None
    drift_units: set[str] = field(default_factory=set)  # of its position residuals


def drift_units(model: Any) -> set[str]:
    """The units of ``model``'s position constraint residuals, whose largest is a run's
    position drift: 'm' (distances: joints keep points together, contacts their height)
    and 'rad' (rotation entries: joints keep axes aligned)."""
    from workbench.mechanics.joints import constraint_units

    planar = model.kind == "planar"
    units = {"m"} if model.nonholonomic else set()
    return units.union(*(constraint_units(j, planar) for j in model.joints.values()))


def problem_model(problem: str, options: str = "") -> Any:
    """The problem's model from its registered plugin and options (JSON), or None."""
    from workbench.plugin import registry

    try:
        parsed = json.loads(options) if options.strip() else None
        return registry.get_problem(problem)(parsed or None).model()
    except Exception:  # noqa: BLE001 - a problem not installed here: traits from rows only
        return None


def model_traits(model: Any) -> tuple[str, list[str]]:
    """The family of ``model`` (:data:`FAMILIES`) and its traits in words."""
    joints = list(model.joints.values())
    cut = [j for j in joints if j.cut]
    rotations = [j for j in joints if j.type in ("spherical", "free")]
    meshes = any(s.kind == "mesh" for b in model.bodies.values() for s in b.shapes)
    traits = [
        f"{model.kind}, {_count(len(model.bodies), 'body', 'bodies')}, "
        f"{_count(len(joints), 'joint', 'joints')}"
    ]
    if cut:
        traits.append(
            f"closed loops ({_count(len(cut), 'cut joint', 'cut joints')}: "
            "position constraints, a DAE or a coordinate partition)"
        )
    if model.nonholonomic:
        rows = _count(
            len(model.nonholonomic),
            "rolling or knife-edge constraint",
            "rolling or knife-edge constraints",
        )
        traits.append(f"nonholonomic ({rows}: velocity constraints)")
    driven = [j.name for j in joints if j.drive is not None]
    if driven:
        traits.append(
            f"rheonomic ({_count(len(driven), 'driven joint', 'driven joints')}: "
            f"{', '.join(driven)}; equations that depend on time)"
        )
    if rotations:
        kinds = sorted({j.type for j in rotations})
        traits.append(f"3D rotations ({', '.join(kinds)} joints: Euler parameters)")
    if meshes:
        traits.append("geometry imported from a robot file")
    if model.nonholonomic:
        family = "nonholonomic"
    elif cut:
        family = "closed loops"
    elif meshes:
        family = "robots (imported geometry)"
    elif rotations:
        family = "rotations (spherical and free joints)"
    else:
        family = "open trees and chains"
    return family, traits


def _count(n: int, one: str, many: str) -> str:
    return f"{n} {one if n == 1 else many}"


def implicit(runs: pd.DataFrame) -> pd.Series:
    """True for runs of an integrator that evaluated Jacobians (an implicit method)."""
    jacobians = pd.to_numeric(runs.get("n_jac"), errors="coerce")
    return (jacobians > 0) if jacobians is not None else pd.Series(False, index=runs.index)


def stiffness(runs: pd.DataFrame) -> str:
    """A sentence on the problem's stiffness from its adaptive runs' statistics ('' when
    the runs cannot tell: no explicit or no implicit adaptive integrator ran). A fixed-step
    run (``fixed_step_s`` finite) is left out: its steps are the step asked, never
    rejected, and say nothing of the problem (rk4's 10,000 steps at 1 ms made a pendulum
    "stiff")."""
    done = runs[runs["status"].isin(["ok", "failed", "timeout"])].copy()
    if "fixed_step_s" in done:
        fixed = np.isfinite(pd.to_numeric(done["fixed_step_s"], errors="coerce"))
        done = done[~fixed]
    for column in ("n_steps", "n_rejected"):  # -1: not reported by the integrator
        values = pd.to_numeric(done.get(column), errors="coerce")
        done[column] = values.where(values >= 0) if values is not None else np.nan
    if done.empty:
        return ""
    by_kind = implicit(done)
    explicit, implicit_runs = done[~by_kind], done[by_kind]
    if explicit.empty or implicit_runs.empty:
        return ""
    ok_explicit, ok_implicit = ok_runs(explicit), ok_runs(implicit_runs)
    lost = 1 - len(ok_explicit) / len(explicit)
    ratios = []
    for rtol in sorted(set(ok_explicit["rtol"]) & set(ok_implicit["rtol"])):
        e = ok_explicit.loc[ok_explicit["rtol"] == rtol, "n_steps"].median()
        i = ok_implicit.loc[ok_implicit["rtol"] == rtol, "n_steps"].median()
        if np.isfinite(e) and np.isfinite(i) and i > 0:
            ratios.append(e / i)
    counted = ok_explicit.dropna(subset=["n_steps", "n_rejected"])
    steps = (counted["n_steps"].sum(), counted["n_rejected"].sum())
    rejected = steps[1] / steps[0] if steps[0] > 0 else np.nan
    ratio = float(np.median(ratios)) if ratios else np.nan
    numbers = []
    if np.isfinite(ratio):
        numbers.append(f"explicit integrators took {ratio:.2g}x the steps of implicit ones")
    if np.isfinite(rejected):
        numbers.append(f"rejected {rejected:.0%} of their steps")
    if lost > 0:
        numbers.append(f"{lost:.0%} of their runs did not finish ok")
    stiff = (
        (np.isfinite(ratio) and ratio >= STIFF_STEP_RATIO)
        or (np.isfinite(rejected) and rejected >= STIFF_REJECTED)
        or (lost >= 0.5 and len(ok_implicit) > 0)
    )
    verdict = "stiff" if stiff else "not stiff"
    return f"{verdict}: " + ", ".join(numbers) if numbers else ""


def pair_family(runs: pd.DataFrame) -> pd.Series:
    """Per run: 'explicit' or 'implicit' integrator with the form the formalism gave it
    (ode, dae, mechanical), e.g. 'explicit ode'."""
    form = (
        runs["form"].astype(object).fillna("").astype(str)
        if "form" in runs
        else pd.Series("", index=runs.index)
    )
    kind = implicit(runs).map({True: "implicit", False: "explicit"})
    return (kind + " " + form).str.strip()


def problem_traits(runs: pd.DataFrame) -> Traits:
    """The :class:`Traits` of one problem's rows (prepared)."""
    first = runs.iloc[0]
    options = str(first.get("problem_options", "") or "")
    name = str(first.get("problem_name", first["problem"]))  # a variant's plugin
    model = problem_model(name, "" if options == "nan" else options)
    family, traits = model_traits(model) if model is not None else ("other", [])
    units = drift_units(model) if model is not None else set()
    return Traits(family, traits, stiffness(runs), model, units)


def favoured(runs: pd.DataFrame, winners: list[str]) -> str:
    """Which families of pairs (:func:`pair_family`) the winning ``winners`` belong to,
    e.g. 'explicit ode (2 of 3 targets)'; '' when none won."""
    if not winners:
        return ""
    trusted = runs[~warned(runs)]
    family_of = dict(zip(trusted["pair"], pair_family(trusted), strict=True))
    counts = pd.Series([family_of.get(w, "?") for w in winners]).value_counts()
    return ", ".join(f"{name} ({n} of {len(winners)})" for name, n in counts.items())
