"""How long a sweep will take, said before it starts, from measured costs.

Each run's cost is the seconds its worker spends on it on an idle machine
(:func:`run_seconds`: its stages, the reference, the recording and the extra timed samples,
scaled by the row's CPU / wall ratio so that a row measured on a busy machine still
counts its own work, not the time it waited for a core; a timeout counts its time limit).
The costs come from, in order: the sweep's own rows in its output directory (a resumed or
re-run sweep), and the cost tables shipped beside the suites
(``workbench/runs/suites/NAME.costs.json``, written by ``python -m benchmarks.suite_costs
NAME``). A run found in neither takes the mean cost of its problem's known runs, else
of all known runs (the estimate then says it is rough); when no run of the sweep nor of its
problems was measured there is no estimate, and :func:`estimate_lines` says so.

The estimate is ``overhead_s + (seconds of the runs to do) / workers``: ``overhead_s`` is
what a sweep costs besides its runs (starting the workers, the report, the recording),
measured with the table. Hardware differs: the figure is a guide, not a promise.
"""

from __future__ import annotations

import json
import math
import statistics
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

from workbench.execution.execute import RunSpec

LONG_S = 300.0  # a sweep estimated longer than this is said to be long (5 min)
ROUGH_SHARE = 0.1  # more runs than this share without a measured cost: a rough estimate


def _number(row: Mapping[str, Any], column: str) -> float:
    try:
        value = float(row.get(column))
    except (TypeError, ValueError):
        return 0.0
    return value if math.isfinite(value) else 0.0


def run_seconds(row: Mapping[str, Any], time_limit: float) -> float:
    """Seconds a worker of an idle machine spends on the run of ``row``."""
    if row.get("status") == "timeout":
        return float(time_limit)
    wall = sum(_number(row, c) for c in ("wall_s", "reference_s", "log_s"))
    wall += max(0.0, _number(row, "repeats") - 1) * _number(row, "integrate_s")
    stages = _number(row, "wall_s")
    busy = min(1.0, _number(row, "cpu_s") / stages) if stages > 0 else 1.0
    return wall * busy


def _key(problem: str, formalism: str, integrator: str, rtol: float) -> str:
    return f"{problem}|{formalism}|{integrator}|{float(rtol):.3e}"


@dataclass
class Costs:
    """Measured seconds a run: by run id, by (problem, formalism, integrator, rtol)."""

    by_id: dict[str, float] = field(default_factory=dict)
    by_key: dict[str, float] = field(default_factory=dict)
    by_problem: dict[str, list[float]] = field(default_factory=dict)
    overhead_s: float = 0.0
    sources: list[str] = field(default_factory=list)
    # where each cost came from (a later source replaces an earlier one), and the sources
    # of the costs :meth:`seconds` used: what the plan line names
    origin: dict[str, str] = field(default_factory=dict)
    problem_origins: dict[str, set[str]] = field(default_factory=dict)
    used: set[str] = field(default_factory=set)

    def add(self, run_id: str, key: str, problem: str, seconds: float, source: str = "") -> None:
        self.by_id[run_id] = seconds
        self.by_key[key] = seconds
        self.by_problem.setdefault(problem, []).append(seconds)
        self.origin[run_id] = self.origin[key] = source
        self.problem_origins.setdefault(problem, set()).add(source)

    def seconds(self, spec: RunSpec) -> tuple[float, str]:
        """(seconds of ``spec``, how they were found: "run", "problem" or "all")."""
        if spec.run_id in self.by_id:
            self.used.add(self.origin.get(spec.run_id, ""))
            return self.by_id[spec.run_id], "run"
        key = _key(spec.problem, spec.formalism, spec.integrator, spec.rtol)
        if key in self.by_key:
            self.used.add(self.origin.get(key, ""))
            return self.by_key[key], "run"
        # the mean, not the median: the estimate is of a sum, and the slow runs make it
        if spec.problem in self.by_problem:
            self.used |= self.problem_origins.get(spec.problem, set())
            return statistics.fmean(self.by_problem[spec.problem]), "problem"
        self.used |= set(self.sources)
        return statistics.fmean(self.by_id.values()), "all"

    def used_sources(self) -> list[str]:
        """The sources of the costs used so far, in :attr:`sources`' order."""
        return [source for source in self.sources if source in self.used] or self.sources


def cost_table(rows: Iterable[Mapping[str, Any]], time_limit: float) -> list[list[Any]]:
    """[run id, problem, formalism, integrator, rtol, seconds] of each row, for a table."""
    return [
        [
            row["run_id"],
            row["problem"],
            row["formalism"],
            row["integrator"],
            float(row["rtol"]),
            round(run_seconds(row, time_limit), 4),
        ]
        for row in rows
    ]


def shipped_tables() -> list[Any]:
    """The cost tables beside the suites (``suites/*.costs.json``)."""
    folder = resources.files("workbench.runs").joinpath("suites")
    return sorted(
        (f for f in folder.iterdir() if f.name.endswith(".costs.json")), key=lambda f: f.name
    )


def known_costs(
    out_rows: Mapping[str, Mapping[str, Any]], time_limit: float, suite: str = ""
) -> Costs:
    """The costs of :func:`estimate_lines`: the rows in OUT first, then the shipped tables
    (the suite's own before the others)."""
    costs = Costs()
    tables = sorted(shipped_tables(), key=lambda f: f.name != f"{suite}.costs.json")
    for table in reversed(tables):  # the suite's own table last: it wins
        data = json.loads(table.read_text("utf-8"))
        source = f"workbench/runs/suites/{table.name}"
        for run_id, problem, formalism, integrator, rtol, seconds in data["runs"]:
            costs.add(run_id, _key(problem, formalism, integrator, rtol), problem, seconds,
                      source)  # fmt: skip
        if table.name == f"{suite}.costs.json" or not costs.overhead_s:
            costs.overhead_s = float(data.get("overhead_s", 0.0))
        costs.sources.append(source)
    measured = [row for row in out_rows.values() if row.get("status")]
    source = "the rows already in the output directory"
    for run_id, problem, formalism, integrator, rtol, seconds in cost_table(measured, time_limit):
        costs.add(run_id, _key(problem, formalism, integrator, rtol), problem, seconds, source)
    if measured:
        costs.sources.append(source)
    return costs


def duration(seconds: float) -> str:
    """``75`` -> ``1 min 15 s``; ``4000`` -> ``1 h 7 min``."""
    seconds = max(0, round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    minutes, rest = divmod(seconds, 60)
    if minutes < 60:
        return f"{minutes} min {rest} s" if minutes < 10 and rest else f"{minutes} min"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes} min"


def estimate(todo: list[RunSpec], costs: Costs, workers: int) -> tuple[float, int] | None:
    """(estimated seconds, runs without a measured cost) of running ``todo``; None when
    no run of it, nor of its problems, was measured."""
    if not todo:
        return 0.0, 0
    if not costs.by_id:
        return None
    found = [costs.seconds(spec) for spec in todo]
    if all(how == "all" for _, how in found):
        return None
    guessed = sum(how != "run" for _, how in found)
    return costs.overhead_s + sum(s for s, _ in found) / max(1, workers), guessed


def estimate_lines(
    todo: list[RunSpec],
    total: int,
    workers: int,
    costs: Costs,
    quick_command: str = "workbench sweep",
) -> list[str]:
    """What a sweep says before it starts: the runs planned and to do, how long they
    should take and from what, and a warning with the quick suite when that is long."""
    planned = f"plan: {total} runs" + (f", {len(todo)} to run" if len(todo) != total else "")
    found = estimate(todo, costs, workers)
    if found is None:
        return [
            f"{planned} on {workers} worker(s); no estimate of the time: no run of these "
            "problems was measured (a resumed sweep uses its own rows)"
        ]
    seconds, guessed = found
    rough = guessed > ROUGH_SHARE * len(todo)
    how = (
        f"rough: {guessed} of {len(todo)} runs have no measured cost"
        if rough
        else "from measured costs"
    )
    lines = [
        f"{planned} on {workers} worker(s); estimated {duration(seconds)} on an idle machine "
        f"({how}: {', '.join(costs.used_sources())})"
    ]
    if seconds > LONG_S:
        lines.append(
            f"warning: this sweep is long (about {duration(seconds)}); for a first look in "
            f"about a minute run `{quick_command}` (the quick suite); Ctrl-C keeps the "
            "finished runs and the same command resumes"
        )
    return lines
