"""What a report says about the runs: labels of pairs, the cheapest pair reaching each
accuracy, the status matrix and the drift at the middle tolerance.

Every function takes the output of :func:`prepare_results` (one row a run) and returns
pandas tables; nothing here draws or writes files.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import pandas as pd

from workbench.errors import ConfigError
from workbench.execution.timing import TIMING_COLUMNS
from workbench.outputs.report.ranking import cheapest_table
from workbench.outputs.report.tables import HEADERS
from workbench.outputs.report.trust import ok_runs, warned

STATUSES: tuple[str, ...] = ("ok", "ok with warnings", "failed", "timeout", "skipped")
TARGET_SCD: tuple[float, ...] = (2.0, 4.0, 6.0, 8.0, 10.0)
REQUIRED_COLUMNS: tuple[str, ...] = ("problem", "formalism", "integrator", "rtol", "status")
NUMERIC_COLUMNS: tuple[str, ...] = (
    "atol",
    "wall_s",
    "cpu_s",
    *TIMING_COLUMNS,
    "integrate_cpu_s_min",
    "integrate_cpu_s_max",
    "n_rhs",
    "n_jac",
    "n_steps",
    "n_rejected",
    "err_max",
    "err_end",
    "err_l2",
    "scd",
    "drift_pos_max",
    "drift_vel_max",
    "drift_nh_max",
    "energy_err_max",
    "invariant_err_max",
    "fixed_step_s",
    "length_scale",
    "reference_accuracy",
)
DRIFT_TABLE_COLUMNS: tuple[str, ...] = (
    "drift_pos_max",
    "drift_vel_max",
    "drift_nh_max",
    "energy_err_max",
    "invariant_err_max",
    "err_end",
    "err_l2",
    "err_max",
    "scd",
)
LABEL_COLUMNS: tuple[str, ...] = ("pair", "formalism_label", "integrator_label")


def prepare_results(results: pd.DataFrame) -> pd.DataFrame:
    """A copy of ``results``: numeric columns as floats, labels of formalism, integrator, pair.

    Raises ConfigError when a required column is missing.
    """
    if not isinstance(results, pd.DataFrame):
        raise ConfigError(f"results must be a pandas DataFrame, got {type(results).__name__}")
    missing = [column for column in REQUIRED_COLUMNS if column not in results.columns]
    if missing:
        raise ConfigError(
            f"results lack the column(s) {', '.join(missing)}; "
            "give a table written by workbench.runs.store (see docs/architecture.md, "
            "'Runs, results, reports')"
        )
    runs = results.copy().reset_index(drop=True)
    for column in NUMERIC_COLUMNS + ("rtol",):
        runs[column] = (
            pd.to_numeric(runs[column], errors="coerce") if column in runs else float("nan")
        )
    for column in ("run_id", "message", "problem_options", "formalism_options",
                   "integrator_options"):  # fmt: skip
        if column not in runs:
            runs[column] = ""
        runs[column] = runs[column].astype(object).fillna("").astype(str)
    if not runs["run_id"].str.len().any():
        runs["run_id"] = [f"run-{index}" for index in range(len(runs))]
    for column in ("problem", "formalism", "integrator", "status"):
        runs[column] = runs[column].astype(str)
    # a problem run with several option sets is several mechanisms: each its own answer
    # (`pendulum[angle=0.3]`); the plugin's name stays in problem_name
    runs["problem_name"] = runs["problem"]
    runs["problem"] = problem_labels(runs)
    runs["formalism_label"], runs["integrator_label"] = pair_labels(runs)
    runs["pair"] = runs["formalism_label"] + " / " + runs["integrator_label"]
    return runs


def problem_labels(runs: pd.DataFrame) -> pd.Series:
    """Each row's problem, with the options that vary between its rows appended
    (``pendulum[angle=0.3]``): one label a mechanism."""
    options = runs.get("problem_options", pd.Series("", index=runs.index))
    options = options.astype(object).fillna("").astype(str)
    return _with_varying_options(runs["problem"].astype(str), options)


def pair_labels(runs: pd.DataFrame) -> tuple[pd.Series, pd.Series]:
    """Formalism and integrator labels per row, with the options that vary appended.

    An option appears in the label only when the same plugin was run with different
    values of it, so curves stay distinguishable and labels stay short.
    """
    formalism = _with_varying_options(runs["formalism"], runs["formalism_options"])
    integrator = _with_varying_options(runs["integrator"], runs["integrator_options"])
    return formalism, integrator


def _with_varying_options(names: pd.Series, options: pd.Series) -> pd.Series:
    labels = names.copy()
    for name in names.unique():
        rows = names == name
        distinct = options[rows].unique()
        if len(distinct) < 2:
            continue
        parsed = {text: _parse_options(text) for text in distinct}
        keys = sorted({key for value in parsed.values() for key in value})
        varying = [
            key for key in keys if len({repr(value.get(key)) for value in parsed.values()}) > 1
        ]
        suffix = {
            text: ",".join(f"{key}={value[key]}" for key in varying if key in value)
            for text, value in parsed.items()
        }
        labels[rows] = [f"{name}[{suffix[text]}]" for text in options[rows]]
    return labels


def _parse_options(text: str) -> dict[str, Any]:
    if not text:
        return {}
    try:
        value = json.loads(text)
    except ValueError:
        return {"options": text}
    return value if isinstance(value, dict) else {"options": value}


def warning_kinds(text: str) -> list[str]:
    """The kinds of warning in a row's ``warnings`` (the words before each ':')."""
    return [w.split(":", 1)[0].strip() for w in str(text or "").split("; ") if w.strip()]


def cheapest_pairs(
    runs: pd.DataFrame, targets: Sequence[float] = TARGET_SCD, cost: str = "wall_s"
) -> pd.DataFrame:
    """For each problem and target scd: the ok run of least ``cost`` (a column, see
    :mod:`workbench.outputs.report.cost`) with scd >= target, its runner-up, margin and
    ties (:func:`workbench.outputs.report.ranking.cheapest_table`, the one ranking the
    report, ``workbench results`` and the LaTeX share).

    One row per (problem, target); problems where no run reached a target say so.
    A run with warnings (:func:`warned`) is never chosen: it may be wrong.
    ``runs`` is the output of :func:`prepare_results`.
    """
    return cheapest_table(runs, targets, cost)


def status_matrix(runs: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Problem x pair table of status counts, and the reasons, each given once.

    A cell reads e.g. ``4 ok, 1 failed [2]``: reason 2 says why. Runs share a reason when
    their status and the kind of their message agree (:func:`reason_key`: the message with
    the model's and plugins' names and the numbers left out), so "formalism 'A' does not
    support loop-closing joints (model 'B')" and the same of another formalism and model
    are one reason, listed once with the problems it concerns, its numbers as its runs
    measured them (one value, or their least and greatest).
    """
    reason_ids: dict[tuple[str, str], int] = {}
    reason_runs: dict[tuple[str, str], list[str]] = {}
    reason_texts: dict[tuple[str, str], list[str]] = {}
    runs = runs.assign(status=runs["status"].where(~warned(runs), OK_WARNED))
    for row in runs[runs["status"] != "ok"].itertuples():
        key = reason_key(row.status, row)
        reason_ids.setdefault(key, len(reason_ids) + 1)
        reason_runs.setdefault(key, []).append(row.problem)
        reason_texts.setdefault(key, []).append(_reason_text(row.status, row))
    problems = list(dict.fromkeys(runs["problem"]))
    pairs = sorted(runs["pair"].unique())
    cells = pd.DataFrame("", index=pd.Index(problems, name="problem"), columns=pairs)
    for (problem, pair), group in runs.groupby(["problem", "pair"], sort=False):
        parts = []
        for status in statuses(group["status"]):
            of_status = group[group["status"] == status]
            text = f"{len(of_status)} {status}"
            if status != "ok":
                keys = {reason_key(status, row) for row in of_status.itertuples()}
                text += " [" + ",".join(str(i) for i in sorted(reason_ids[k] for k in keys)) + "]"
            parts.append(text)
        cells.loc[problem, pair] = ", ".join(parts)
    cells = cells.replace("", "-")
    reasons = []
    for key, number in reason_ids.items():
        where = list(dict.fromkeys(reason_runs[key]))
        shown = ", ".join(where[:6]) + (f" and {len(where) - 6} more" if len(where) > 6 else "")
        count = len(reason_runs[key])
        said = _with_numbers(key[1], reason_texts[key])
        reasons.append(f"[{number}] {key[0]}: {said} ({count} run(s); problems: {shown})")
    return cells, reasons


OK_WARNED = "ok with warnings"  # an ok row whose health audit found something

_MODEL_NAME = re.compile(r"\s*\(model '[^']*'\)")
_QUOTED_NAME = re.compile(r"(formalism|integrator|problem) '[^']*'")
_NUMBER = re.compile(r"(?<![\w.])\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?!\w)")


def reason_key(status: str, row: Any) -> tuple[str, str]:
    """The status and the kind of reason of a not-ok row: for a warned run the kinds of its
    warnings; otherwise its message without the model's name, plugin names and numbers
    (times reached, step sizes), which differ from run to run for one and the same reason."""
    return status, _NUMBER.sub("#", _reason_text(status, row))


def _reason_text(status: str, row: Any) -> str:
    """The reason of :func:`reason_key` with its numbers still in."""
    if status == OK_WARNED:
        kinds: dict[str, str] = {}
        for kind in warning_kinds(row.warnings):
            kinds.setdefault(_NUMBER.sub("#", kind), kind)  # the first of each kind
        return ", ".join(kinds.values())
    text = _one_line(row.message) or "no reason recorded"
    text = _MODEL_NAME.sub("", text)
    return _QUOTED_NAME.sub(lambda m: f"the {m.group(1)}", text)


def _with_numbers(reason: str, texts: list[str]) -> str:
    """``reason`` (a :func:`reason_key` text) with each '#' back as the number its runs'
    ``texts`` hold there: the one number when they all agree, else their least and greatest
    ('9.77 to 9.9'); a reason printed '# s' in a paper's table, no number measured."""
    found = [_NUMBER.findall(text) for text in texts]
    holes = reason.count("#")
    if not found or any(len(numbers) != holes for numbers in found):
        return reason  # (a '#' of the message's own)
    pieces = reason.split("#")
    out = [pieces[0]]
    for k, piece in enumerate(pieces[1:]):
        values = sorted({numbers[k] for numbers in found}, key=float)
        out.append((values[0] if len(values) == 1 else f"{values[0]} to {values[-1]}") + piece)
    return "".join(out)


def statuses(values: Iterable[str]) -> list[str]:
    """The distinct statuses in ``values``: the known ones in :data:`STATUSES` order first."""
    present = set(values)
    return [s for s in STATUSES if s in present] + sorted(present - set(STATUSES))


def status_counts(runs: pd.DataFrame) -> str:
    """``"3 ok, 1 ok with warnings, 1 failed"``: how many runs ended in each status, the
    ok runs with warnings apart (as the status table and `workbench results` count them)."""
    from workbench.outputs.report.trust import warned as with_warnings

    counts = runs["status"].value_counts()
    warned = int(((runs["status"] == "ok") & with_warnings(runs)).sum())
    parts = []
    for status in statuses(runs["status"]):
        count = int(counts[status]) - (warned if status == "ok" else 0)
        if count:
            parts.append(f"{count} {status}")
        if status == "ok" and warned:
            parts.append(f"{warned} ok with warnings")
    return ", ".join(parts)


def _one_line(text: str, limit: int = 300) -> str:
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


def middle_tolerance(rtols: Iterable[float]) -> float | None:
    """The middle of the distinct finite tolerances (the larger middle one if even)."""
    values = sorted({float(r) for r in rtols if np.isfinite(r)})
    return values[len(values) // 2] if values else None


def drift_runs(runs: pd.DataFrame) -> tuple[float | None, pd.DataFrame]:
    """The middle tolerance of a problem's ok runs and one ok run per pair at it."""
    ok = ok_runs(runs)
    rtol = middle_tolerance(ok["rtol"])
    if rtol is None:
        return None, ok.iloc[:0]
    chosen = ok[np.isclose(ok["rtol"], rtol, rtol=1e-9, atol=0)]
    return rtol, chosen.drop_duplicates("pair").sort_values("pair")


def drift_left_out(runs: pd.DataFrame, rtol: float) -> list[str]:
    """The pairs run at ``rtol`` that no ok run of :func:`drift_runs` stands for, each with
    its status there ('f / i (timeout)'): a drift table's caption said 'every pair' over
    the pairs that finished."""
    at = runs[np.isclose(runs["rtol"], rtol, rtol=1e-9, atol=0)]
    shown = set(ok_runs(at)["pair"])
    return [
        f"{pair} ({', '.join(statuses(group['status']))})"
        for pair, group in at.groupby("pair", sort=True)
        if pair not in shown
    ]


def drift_table(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per pair at the middle tolerance: the maxima over time of the drifts and
    errors (columns left out when no run measured them)."""
    _rtol, chosen = drift_runs(runs)
    columns = [c for c in DRIFT_TABLE_COLUMNS if chosen[c].notna().any()]
    return chosen[["pair", *columns]].reset_index(drop=True)


def drift_table_contents(table: pd.DataFrame, units: Iterable[str] = ()) -> str:
    """What a :func:`drift_table` holds, for its caption: only the quantities it has a
    column of (a caption named invariant errors where no run measured one), and the units
    of its drift (``units`` of the model's residuals, traits.drift_units; the headers say
    'm or rad' for every problem)."""
    # their headers without 'max' and the unit: 'max position drift [m or rad]'
    maxima = [HEADERS[c].removeprefix("max ").split(" [")[0] for c in DRIFT_TABLE_COLUMNS
              if c in table and c.endswith("_max") and not c.startswith("err_")]  # fmt: skip
    parts = []
    if maxima:  # 'largest a, b and c'
        head = ", ".join(maxima[:-1])
        parts.append("largest " + (f"{head} and " if head else "") + maxima[-1])
    if table.columns.str.startswith("err_").any():
        parts.append("pose errors (end, L2 and maximum over the samples)")
    if "scd" in table:
        parts.append("scd")
    drifts = [unit for c, unit in (("drift_pos_max", "m"), ("drift_vel_max", "m/s")) if c in table]
    if drifts and set(units) == {"m"}:
        parts.append(f"drift in {' and '.join(drifts)}: every position constraint of this "
                     "model is a distance")  # fmt: skip
    elif drifts and set(units) == {"m", "rad"}:
        parts.append("drift in mixed units: the largest residual, a distance (m) or an axis "
                     "misalignment (a rotation entry, about the angle in rad), per second "
                     "for velocity")  # fmt: skip
    return "; ".join(parts) or "the pairs"


def run_environment(runs: pd.DataFrame) -> list[str]:
    """What the runs recorded about where they ran: 'name: value[, value...]' per column
    (``version_*``, ``machine``, ``cpu_count`` of the result rows; distinct values)."""
    columns = [c for c in runs.columns if c.startswith("version_")]
    columns += [c for c in ("machine", "cpu_count") if c in runs.columns]
    lines = []
    for column in columns:
        values = [str(v) for v in runs[column].dropna().unique() if str(v) not in ("", "nan")]
        if values:
            name = column.removeprefix("version_")
            lines.append(f"{name}: {', '.join(sorted(values)[:5])}")
    return lines


def oversubscription_warning(runs: pd.DataFrame) -> str:
    """A warning for the top of the page when runs were timed with more workers than the
    machine had idle cores (:func:`workbench.execution.timing.oversubscribed`: from each row's
    load average, workers and CPUs), so their times include waiting for a core; '' if
    none was (or nothing was recorded)."""
    from workbench.execution.timing import oversubscribed

    columns = ("load_avg", "workers", "cpu_count")
    if runs.empty or not all(c in runs for c in columns):
        return ""
    values = runs[list(columns)].apply(pd.to_numeric, errors="coerce")
    flagged = values[[oversubscribed(*row) for row in values.itertuples(index=False)]]
    if flagged.empty:
        return ""
    return (
        f"{len(flagged)} of {len(runs)} runs were timed with more workers than idle cores "
        f"(up to {flagged['workers'].max():g} workers on {flagged['cpu_count'].min():g} CPUs "
        f"at a load average up to {flagged['load_avg'].max():.2f}): their times include "
        "waiting for a core; compare costs with care, or sweep again with fewer --jobs on "
        "a quieter machine"
    )


STALLED_SPAN = 2.0
"""Decades of rtol over which a pair's scd must move before it is called stalled."""
STALLED_BEHIND = 3.0
"""Digits behind the problem's best pair that a stalled pair's best scd must be."""


def reference_source(runs: pd.DataFrame) -> str:
    """Where one problem's reference came from, as most of its rows say it (the cache file
    it was read from left out); for a reference computed with a formalism that is also
    swept, that its runs are scored against their own equations. '' when no row says."""
    if "reference" not in runs:
        return ""
    said = runs["reference"].dropna().astype(str)
    said = said[said != ""].str.replace(r" \(read from [^()]*\)$", "", regex=True)
    if said.empty:
        return ""
    text = said.mode().iloc[0]
    if text.startswith("computed: "):
        formalism = text.removeprefix("computed: ").split(" + ")[0].split("(")[0]
        if formalism in set(runs.get("formalism", pd.Series(dtype=str)).astype(str)):
            text += (
                f"; {formalism}'s runs are scored against their own equations (their error "
                "is the integration's alone; the other formalisms' agreement checks them)"
            )
    return text


def stalled_pairs(runs: pd.DataFrame) -> list[str]:
    """Pairs whose error does not shrink with the tolerance while other pairs' does:
    over ``STALLED_SPAN`` decades of rtol the scd of their trusted runs (ok, no warning)
    moves by less than one digit, and their best is ``STALLED_BEHIND`` digits behind the
    best of another pair on the problem (``runs`` prepared). Each run looks fine on its
    own (a formalism whose pendulum never falls conserves its energy and constraints:
    its rows were ok at scd 0.8, beside 5.9), so only the runs together show it; one
    sentence a pair, for the first screen. Runs with warnings say so already; problems
    with contacts are left out: a time step or a penalty stiffness sets those errors,
    not rtol (the nonsmooth suite's penalty-contact pairs stall by design)."""
    ok = ok_runs(runs)
    ok = ok[~warned(ok) & np.isfinite(pd.to_numeric(ok["scd"], errors="coerce"))]
    found = []  # (runs with warnings say so already: a pair left its branch, ...)
    for problem, rows in ok.groupby("problem", sort=False):
        contact = pd.to_numeric(rows.get("penetration_max", pd.Series(dtype=float)), "coerce")
        if contact.notna().any():  # a time step or a penalty stiffness sets the error
            continue
        for pair, own in rows.groupby("pair", sort=False):
            decades = np.log10(own["rtol"].max() / own["rtol"].min())
            others = rows[rows["pair"] != pair]
            steps = pd.to_numeric(own.get("fixed_step_s", pd.Series(dtype=float)), "coerce")
            if decades < STALLED_SPAN or others.empty or steps.dropna().nunique() == 1:
                continue  # (one fixed step for every rtol: the tolerance sets no step)
            best = others.loc[others["scd"].idxmax()]
            low, high = own["scd"].min(), own["scd"].max()
            if high - low < 1.0 and high <= best["scd"] - STALLED_BEHIND:
                formalism = str(own["formalism"].iloc[0])
                found.append(
                    f"{problem}: {pair} stays at scd {_span(low, high)} from rtol "
                    f"{own['rtol'].max():g} to {own['rtol'].min():g} while {best['pair']} "
                    f"reaches {best['scd']:.3g}: something the tolerance does not control "
                    f"sets its error, an option of its integrator or its equations (python "
                    f"-m workbench.testing formalism {formalism} checks them)"
                )
    return found


def _span(low: float, high: float) -> str:
    """'0.78' or '0.78-0.91': a range of scd, one number when both ends print alike."""
    return f"{low:.2g}" if f"{low:.2g}" == f"{high:.2g}" else f"{low:.2g}-{high:.2g}"


def coverage_notice(runs: pd.DataFrame, plan: dict[str, Any] | None) -> str:
    """A notice for the first screen when the rows are not the whole sweep that was
    planned (``plan``: :func:`workbench.runs.store.load_plan`): planned vs present runs,
    and rows of other sweeps (the first three named); '' when they are the plan exactly, or
    no plan is known. Its heading: :func:`coverage_heading`."""
    planned, have, extra = _coverage(runs, plan)
    parts = []
    if have < planned:
        parts.append(
            f"partial results: the sweep ({plan.get('source') or 'its specification'}) planned "
            f"{planned} runs and {have} of them have a row here, {planned - have} missing "
            "(the sweep was interrupted, or the rows were filtered): run the same "
            "`workbench sweep` again to complete it"
        )
    if len(extra):
        other = len(extra)
        named = "; ".join(_run_label(row) for _, row in extra.head(3).iterrows())
        parts.append(
            f"{other} row(s) come from other sweeps run in this directory, not from this "
            f"sweep's plan ({named}{'; ...' if other > 3 else ''}), and count in the verdicts "
            "like its own"
        )
    return "; ".join(parts)


def coverage_heading(runs: pd.DataFrame, plan: dict[str, Any] | None) -> str:
    """The heading of :func:`coverage_notice`: "Not the whole sweep" when planned runs have
    no row, "Not this sweep alone" when rows of other sweeps are counted, or both."""
    planned, have, extra = _coverage(runs, plan)
    missing, more = have < planned, len(extra) > 0
    if missing and more:
        return "Not the whole sweep, and not it alone"
    return "Not the whole sweep" if missing else "Not this sweep alone" if more else ""


def _coverage(runs: pd.DataFrame, plan: dict[str, Any] | None) -> tuple[int, int, pd.DataFrame]:
    """Runs planned, how many of them have a row, and the rows of runs not planned (one a
    run, by run_id); all zero and none without a plan."""
    if not plan:
        return 0, 0, runs.iloc[:0]
    planned = set(map(str, plan.get("run_ids", [])))
    ids = runs["run_id"].astype(str)
    extra = runs[~ids.isin(planned)].drop_duplicates("run_id")
    return len(planned), len(planned & set(ids)), extra.sort_values("run_id")


def _run_label(row: pd.Series) -> str:
    """'run 0123abcd: PROBLEM, FORMALISM / INTEGRATOR, rtol 1e-10', from the columns a
    row has (prepared or as loaded)."""
    pair = row.get("pair") or " / ".join(str(row.get(k, "?")) for k in ("formalism", "integrator"))
    rtol = pd.to_numeric(row.get("rtol"), errors="coerce")
    return f"run {row['run_id']}: {row.get('problem', '?')}, {pair}" + (
        f", rtol {rtol:g}" if np.isfinite(rtol) else ""
    )


def status_by_problem(runs: pd.DataFrame, matrix: pd.DataFrame) -> pd.DataFrame:
    """The status matrix (:func:`status_matrix`) folded to a line a problem, for print:
    runs, how many ended in each status, and the reasons ([n]) of the others."""
    flagged = runs.assign(status=runs["status"].where(~warned(runs), OK_WARNED))
    rows = []
    for problem, group in flagged.groupby("problem", sort=False):
        counts = group["status"].value_counts()
        row = {"problem": problem, "runs": len(group)}
        row |= {status: int(counts.get(status, 0)) for status in STATUSES}
        cells = " ".join(matrix.loc[problem]) if problem in matrix.index else ""
        numbers = sorted({int(n) for ids in re.findall(r"\[([\d,]+)\]", cells)
                          for n in ids.split(",")})  # fmt: skip
        row["reasons"] = ", ".join(f"[{n}]" for n in numbers)
        rows.append(row)
    return pd.DataFrame(rows, columns=["problem", "runs", *STATUSES, "reasons"])
