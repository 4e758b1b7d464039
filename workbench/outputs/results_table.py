"""What ``workbench results`` prints: a summary by default, or chosen rows and columns.

The default is one line a problem (runs by status, the best scd reached without warnings,
the pair that reached it at least cost, in the report's cost measure and with the
report's ranking, ties included), not every row of a sweep; ``by="pair"``
gives one line a problem x pair, ``by="run"`` every run (an ``ok`` run whose health audit
warned shows as ``ok with warnings``, as in the report's status table: its scd may be
capped by the reference's accuracy, not measured). Options are readable columns
(``formalism.index``, ``integrator.step``), not JSON strings; a table of runs says those
the same in all its rows once, in its caption, and a run's others that are not its
plugins' defaults in one column, ``options`` (``index=3, rho_inf=0.9``). Rows are filtered by
conditions such as ``problem=my-problem``, ``scd>=6`` or ``status!=skipped``; sorted by
columns (``-scd``: descending); printed as a terminal table, CSV, Markdown or LaTeX (the
report's writers: readable headers with units, one number format a column).

The cost is the report's (:func:`workbench.outputs.report.cost.resolve_cost`: the median CPU
time of the integration, ``integrate_cpu_s``, or what it falls back to for old rows), so
``workbench results`` and the report name the same cheapest pair; the table's
``attrs["cost"]`` states it for the caption.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from workbench.errors import ConfigError
from workbench.outputs.report.analysis import OK_WARNED, prepare_results, warned
from workbench.outputs.report.cost import resolve_cost
from workbench.outputs.report.decision import FALLBACK_TARGETS
from workbench.outputs.report.ranking import Decision, decide
from workbench.outputs.report.tables import latex_table, markdown_table

FORMATS: tuple[str, ...] = ("table", "csv", "markdown", "latex")
ROW_COLUMNS: tuple[str, ...] = (
    "problem", "formalism", "integrator", "rtol", "status", "scd", "err_l2", "wall_s", "n_rhs",
)  # fmt: skip
"""The columns of ``by="run"`` when none are named, ``wall_s`` replaced by the cost measure
the summary ranks by (then ``options``: a run's options that are not its plugins'
defaults, where some are)."""
GROUPINGS: tuple[str, ...] = ("problem", "pair", "run")
RUN_SCD = "run scd"
"""A summary line's column: the scd of the run it shows (rtol, cost), beside the best."""
KEY_COLUMNS = frozenset({"run_id", "problem", "pair", "formalism", "integrator", "rtol"})
"""Leading columns that say which run or group a line is: repeated in every part of a
LaTeX table split to fit the page."""
CONDITION = re.compile(r"^\s*([A-Za-z0-9_.\- ]+?)\s*(<=|>=|!=|==|=|<|>)\s*(.*?)\s*$")


def with_option_columns(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with its JSON option columns spread into one column an option
    (``problem.initial_angle``, ``formalism.index``, ``integrator.step``; empty where a
    plugin has no such option)."""
    out = frame.copy()
    for kind in ("problem", "formalism", "integrator"):
        column = f"{kind}_options"
        if column not in out:
            continue
        parsed = [_options(text) for text in out[column].astype(object).fillna("").astype(str)]
        keys = sorted({key for options in parsed for key in options})
        for key in keys:
            out[f"{kind}.{key}"] = [options.get(key, "") for options in parsed]
        out = out.drop(columns=[column])
    return out


def changed_options(runs: pd.DataFrame) -> list[dict[str, str]]:
    """Each row's options that differ from its plugins' defaults, as ``{"formalism.index":
    "3"}`` (values as JSON; every option of a plugin not registered here)."""
    from workbench.plugin.registry import non_default_options

    seen: dict[tuple[str, str, str], dict[str, str]] = {}
    out: list[dict[str, str]] = [{} for _ in range(len(runs))]
    for kind in ("problem", "formalism", "integrator"):
        if f"{kind}_options" not in runs or kind not in runs:
            continue
        texts = runs[f"{kind}_options"].astype(object).fillna("").astype(str)
        names = runs.get("problem_name", runs[kind]) if kind == "problem" else runs[kind]
        for changed, name, text in zip(out, names.astype(str), texts, strict=True):
            if (kind, name, text) not in seen:
                seen[kind, name, text] = {
                    f"{kind}.{key}": json.dumps(value, default=str).replace('"', "")
                    for key, value in non_default_options(kind, name, _parsed(text)).items()
                }
            changed.update(seen[kind, name, text])
    return out


def options_text(changed: Sequence[dict[str, str]], leave_out: Sequence[str]) -> list[str]:
    """``changed`` (:func:`changed_options`) as ``index=3, rho_inf=0.9`` a row, but for the
    options in ``leave_out`` (said in the caption); an option is named without its kind
    unless the other kind has one of that name."""
    names = {c for row in changed for c in row if c not in leave_out}
    keys = [c.split(".", 1)[1] for c in names]
    short = {c: k if keys.count(k) == 1 else c for c, k in zip(names, keys, strict=True)}
    order = sorted(names, key=lambda c: (c.split(".")[0] != "problem",
                                         c.split(".")[0] != "formalism", c))  # fmt: skip
    return [", ".join(f"{short[c]}={row[c]}" for c in order if c in row) for row in changed]


def _options(text: str) -> dict[str, str]:
    return {
        str(k): v if isinstance(v, int | float | str) else json.dumps(v)
        for k, v in _parsed(text).items()
    }


def _parsed(text: str) -> dict[str, Any]:
    """A row's options column (JSON text) as its dict; text that is not a JSON object is
    one option, ``options``."""
    if not text.strip():
        return {}
    try:
        value = json.loads(text)
    except ValueError:
        return {"options": text}
    return value if isinstance(value, dict) else {"options": str(value)}


UNREPORTED_COUNTS = ("n_jac", "n_steps", "n_rejected", "n_lu", "n_newton")
"""Counts a row holds as -1 when its integrator does not report them: shown empty (as
anything not measured), not as a count of -1; ``--where`` sees the stored -1."""


def filter_rows(frame: pd.DataFrame, conditions: Sequence[str]) -> pd.DataFrame:
    """The rows meeting every condition ``column OP value`` (OP one of = != < <= > >=, and
    == for =; numbers compare as numbers, the rest as text)."""
    keep = pd.Series(True, index=frame.index)
    for condition in conditions:
        match = CONDITION.match(condition)
        if not match:
            raise ConfigError(
                f"--where {condition!r}: write COLUMN OP VALUE with OP one of = != < <= > >= "
                "(e.g. status=ok, scd>=6)"
            )
        column, op, value = match.groups()
        op = "=" if op == "==" else op  # as Python and pandas spell it
        _check_columns(frame, [column], "--where")
        values = frame[column]
        number = pd.to_numeric(pd.Series([value]), errors="coerce").iloc[0]
        numeric = pd.to_numeric(values, errors="coerce")
        if np.isfinite(number) and numeric.notna().any():
            left, right = numeric, number
        elif value.strip().lower() == "nan" and op in ("=", "!="):  # not measured
            left, right = numeric.isna(), op == "="
            op = "="
        elif pd.api.types.is_numeric_dtype(values) and not pd.api.types.is_bool_dtype(values):
            # compared as text, `scd=` matched no row and `scd!=` every row
            raise ConfigError(f"--where {condition!r}: {column} holds numbers; give one "
                              f"(e.g. {column}{op}6), not {value!r}")  # fmt: skip
        elif op in ("=", "!="):
            left, right = values.astype(str), value
        else:
            raise ConfigError(f"--where {condition!r}: {op} needs a number, not {value!r}")
        keep &= {
            "=": left == right,
            "!=": left != right,
            "<": left < right,
            "<=": left <= right,
            ">": left > right,
            ">=": left >= right,
        }[op]
    return frame[keep]


def rows_where(frame: pd.DataFrame, conditions: Sequence[str]) -> pd.DataFrame:
    """The rows of ``frame`` (a store's rows, as they are) that meet ``conditions`` as
    ``workbench results --where`` reads them: with the report's labels (``pair``) and a
    column an option (``formalism.index``); what ``workbench record`` runs again."""
    if not conditions:
        return frame
    kept = filter_rows(with_option_columns(prepare_results(frame)), conditions)
    return frame.iloc[list(kept.index)]  # prepare_results numbers the rows from 0


def unmatched(frame: pd.DataFrame, conditions: Sequence[str]) -> list[str]:
    """For the ``column=value`` conditions of :func:`filter_rows` whose value no row has
    (a misspelled problem name), one text each naming the values the column has."""
    said = []
    for condition in conditions:
        match = CONDITION.match(condition)
        if not match or match.group(2) not in ("=", "==") or match.group(1) not in frame.columns:
            continue
        column, _, value = match.groups()
        values = frame[column].astype(str)
        if not values.eq(value).any():
            known = sorted(set(values))
            listed = ", ".join(known[:20]) + (", ..." if len(known) > 20 else "")
            said.append(f"no run has {column}={value} (its values: {listed})")
            names = frame.get("problem_name")
            if column == "problem" and names is not None and names.astype(str).eq(value).any():
                said.append(f"its runs are named with their problem options: "
                            f"problem_name={value} keeps them all")  # fmt: skip
    return said


def sort_rows(frame: pd.DataFrame, keys: Sequence[str]) -> pd.DataFrame:
    """``frame`` sorted by ``keys`` (``-name``: descending); missing values last."""
    if not keys:
        return frame
    columns = [key.removeprefix("-") for key in keys]
    _check_columns(frame, columns, "--sort")
    ascending = [not key.startswith("-") for key in keys]
    return frame.sort_values(columns, ascending=ascending, na_position="last", kind="stable")


def _check_columns(frame: pd.DataFrame, columns: Sequence[str], option: str) -> None:
    """ConfigError naming the columns ``frame`` lacks: the closest it has first (a typo
    among a hundred columns), then all of them."""
    import difflib

    unknown = [column for column in columns if column not in frame.columns]
    if unknown:
        close = [
            match
            for column in unknown
            for match in difflib.get_close_matches(column, list(map(str, frame.columns)), n=3)
        ]
        hint = f" (did you mean {', '.join(dict.fromkeys(close))}?)" if close else ""
        raise ConfigError(
            f"{option}: no column {', '.join(map(repr, unknown))}{hint}; the columns are "
            f"{', '.join(map(str, frame.columns))}"
        )


def summary(runs: pd.DataFrame, keys: Sequence[str], cost: str = "integrate_cpu_s") -> pd.DataFrame:
    """One row a group of ``keys``: runs, how many ended in each status (ok, ok with
    warnings, failed, timeout, skipped: they add up to the runs), the best scd of an
    ok run without warnings, and the pair, rtol, ``cost`` and rhs evaluations of the
    cheapest such run reaching the target: the highest of the report's accuracy targets
    (:data:`~workbench.outputs.report.decision.FALLBACK_TARGETS`, scd 2 to 10) such a run
    reached (the best scd when none; not a column of a line a problem, the table was too
    wide: its verdict begins with it; a column of a line a pair), with its margin or tie
    (:func:`workbench.outputs.report.ranking.decide`, the report's ranking). Ranked at
    the best scd itself, the line named whichever run reached the last digit, almost
    always alone ("only pair"), not the cheapest of those that reach a target."""
    rows = []
    for key, group in runs.groupby(list(keys), sort=False):
        trusted = group[(group["status"] == "ok") & ~warned(group) & np.isfinite(group["scd"])]
        best = trusted["scd"].max() if not trusted.empty else np.nan
        target = max((t for t in FALLBACK_TARGETS if best >= t), default=best)
        decision = decide(group, target, cost) if np.isfinite(best) else None
        cheapest = decision.run if decision is not None else None
        row = dict(zip(keys, key if isinstance(key, tuple) else (key,), strict=True))
        ok = group["status"] == "ok"
        row |= {"runs": len(group), "ok": int((ok & ~warned(group)).sum())}
        row |= {"ok with warnings": int((ok & warned(group)).sum())}
        for status in ("failed", "timeout", "skipped"):
            row[status] = int((group["status"] == status).sum())
        row["scd"] = best  # (the target, the highest even scd <= it: said in the caption)
        if "pair" in keys:  # no verdict to say it: the target the run shown was chosen at
            row["target"] = target
        if "pair" not in keys:
            row["pair"] = cheapest["pair"] if cheapest is not None else ""
        # the run shown, by its own scd: the line's scd is the best of the group, often
        # another run's (the tightest rtol), which read as this rtol's accuracy
        for column in dict.fromkeys((RUN_SCD, "rtol", cost, "n_rhs")):
            source = "scd" if column == RUN_SCD else column
            row[column] = cheapest[source] if cheapest is not None else np.nan
        if "pair" not in keys:
            row["verdict"] = _verdict(decision)
        rows.append(row)
    return pd.DataFrame(rows)


def _verdict(decision: Decision | None) -> str:
    """The line's verdict, led by the target it was judged at (the line's scd column is
    the best reached, which the named pair need not have reached)."""
    if decision is None or decision.pair is None:
        return ""
    at = f"at scd {decision.target:.3g}, "
    if decision.is_tie:
        return at + "tie: " + "; ".join(decision.tied)
    return at + decision.ahead_of()


def caption(table: pd.DataFrame, runs: int, by: str, path: str, statement: str) -> str:
    """The caption of the printed table: what a line is, of how many runs, and where
    they are (``path`` '': not said, as in a paper's table, where the folder on this
    machine means nothing); the cost measure of a summary."""
    where = f" in {path}" if path else ""
    if by == "run":
        shown = f"{len(table)} of the {runs} runs" if len(table) != runs else f"The {runs} runs"
        same = table.attrs.get("same")
        return f"{shown}{where}" + (f"; in each of them {same}" if same else "")
    lines = {"problem": "a line a problem", "pair": "a line a problem and pair"}[by]
    return (
        f"The {runs} runs{where}, {lines}: the best scd reached without warnings, the "
        f"highest target of scd 2, 4, 6, 8, 10 reached and the cheapest run reaching it "
        f"(its own scd, rtol and cost; {statement})"
    )


LEGEND: dict[str, str] = {
    "scd": "scd: correct significant digits at the end, -log10(end error / length scale L)",
    RUN_SCD: "its scd: that of the run shown, the cheapest reaching the target",
    "rtol": "rtol: the relative tolerance its integrator was given",
}
"""What the terse headers of the printed table mean (the report's page says it once)."""


def legend(table: pd.DataFrame) -> str:
    """One line saying what the columns of ``table`` in :data:`LEGEND` mean ('' if none),
    under the table as printed on a terminal (a CSV or LaTeX stays as it was)."""
    return "; ".join(text for column, text in LEGEND.items() if column in table)


def results_table(
    frame: pd.DataFrame,
    *,
    by: str = "problem",
    columns: Sequence[str] = (),
    where: Sequence[str] = (),
    sort: Sequence[str] = (),
    cost: str | None = None,
) -> pd.DataFrame:
    """The table ``workbench results`` prints, from the rows of ``load_results``:
    ``by`` "problem" or "pair" (:func:`summary`) or "run" (the rows themselves); ``cost``
    a measure of :data:`~workbench.outputs.report.cost.COST_MEASURES` (default the
    report's default)."""
    if by not in GROUPINGS:
        raise ConfigError(f"--by {by!r}: choose one of {', '.join(GROUPINGS)}")
    prepared = prepare_results(frame)
    cost = resolve_cost(prepared, cost)
    runs = filter_rows(with_option_columns(prepared), where)
    if by == "run":
        options = [c for c in runs.columns if c.startswith(("formalism.", "integrator."))]
        # an option with one value in every row shown is said once, in the caption: a
        # column of it widened the table past a page and told nothing; the others, where
        # not a plugin's default, are one column (a column an option was a page wide)
        same = {c: runs[c].iloc[0] for c in options if len(runs) and runs[c].nunique() == 1}
        # the run's cost in the measure the summary and the report rank by (not the whole
        # run's wall time beside a summary of integration CPU)
        shown = [cost.column if c == "wall_s" else c for c in ROW_COLUMNS]
        if not columns or "options" in columns:  # (the plugins' defaults: a registry lookup)
            changed = changed_options(prepared.loc[runs.index])
            runs["options"] = options_text(changed, list(same))
            shown += ["options"] if runs["options"].ne("").any() else []
        chosen = list(columns) or shown
        _check_columns(runs, chosen, "--columns")
        table = runs[chosen].copy()
        if "status" in table:  # the status table's word: a warned run's scd may be capped
            flagged = (table["status"] == "ok") & warned(runs)
            table["status"] = table["status"].mask(flagged, OK_WARNED)
        for column in [c for c in table.columns if c in UNREPORTED_COUNTS]:
            table[column] = table[column].where(table[column] != -1)  # shown empty
        if not columns:  # said once: the options not at their plugins' defaults
            # (a default said nothing: "integrator.first_step=null" in a paper's caption)
            changed = changed_options(prepared.loc[runs.index])
            moved = {key for options in changed for key in options}
            table.attrs["same"] = ", ".join(
                f"{c}={v}" for c, v in same.items() if v != "" and c in moved
            )
    else:
        table = summary(runs, ["problem"] if by == "problem" else ["problem", "pair"], cost.column)
        if columns:
            _check_columns(table, columns, "--columns")
            table = table[list(columns)]
    table = sort_rows(table, sort).reset_index(drop=True)
    if by != "run":
        table.attrs["cost"] = f"cheapest by {cost.statement().removeprefix('cost measure: ')}"
    return table


def render(table: pd.DataFrame, fmt: str, caption: str) -> str:
    """``table`` as CSV, Markdown or LaTeX (booktabs, captioned) text."""
    if fmt == "csv":
        return table.to_csv(index=False)
    if fmt == "markdown":
        return markdown_table(table)
    if fmt == "latex":  # a table split to fit the page repeats what a row is about
        keys = next((k for k, c in enumerate(table.columns) if c not in KEY_COLUMNS), 0)
        return latex_table(table, caption=caption, label="tab:results", keys=keys or None)
    raise ConfigError(f"--format {fmt!r}: choose one of {', '.join(FORMATS)}")
