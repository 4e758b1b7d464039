"""Recording done runs afterwards: ``workbench record OUT`` (a sweep run without one).

A sweep's recording costs a tiny run about as much as everything else outside its
integration (docs/performance.md), and a recording of 10,000 runs is more than a viewer
shows. ``workbench sweep --no-recording`` writes none; :func:`record_runs` then records the
runs chosen (``--where``, as ``workbench results`` chooses rows) by running them again in
the local pool, as a sweep records again the runs a killed worker left unrecorded: their
rows and series are kept as they are, their recordings merged into ``OUT/recording.rrd``.

Only rows that can be run again as they were are recorded: status ``ok`` (a run that failed
or timed out has no whole trajectory to show), not stale (the code that made the row
changed: running it again would show another trajectory than the row's), and made again
with the same run id from the row's keys. A results folder is data (docs/safety.md): a row
whose problem names files (a robot file, its package and allowed folders) outside OUT is
run again only when the user names their folder (``--allow-root``), so that someone
else's folder cannot make the workbench read the user's files into a recording.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from workbench.errors import ConfigError
from workbench.execution.execute import RunSpec
from workbench.execution.timing import Timing
from workbench.files import check_writable
from workbench.plugin.robot_problem import FILE_OPTIONS
from workbench.runs import store
from workbench.runs.local_pool import merge_run_recordings, run_local
from workbench.runs.out_lock import out_lock
from workbench.runs.progress import progress_bar
from workbench.runs.recording_batches import unwritten_runs
from workbench.runs.resume import stale_reason

if TYPE_CHECKING:
    import pandas as pd

DEFAULT_TIME_LIMIT = 300.0
"""Seconds a run may take when it is run again (its row says how long it took before)."""


@dataclass
class RecordSummary:
    recording: Path | None
    recorded: int
    left_out: Counter = field(default_factory=Counter)  # why -> runs not recorded
    failed: list[str] = field(default_factory=list)  # run ids whose run again failed


def spec_of_row(row: dict[str, Any]) -> RunSpec | None:
    """The run of a result row (its options as dicts or JSON text), or None when the row's
    keys do not make its run id again (a row written by other code)."""
    try:
        spec = RunSpec(
            str(row["problem"]), str(row["formalism"]), str(row["integrator"]),
            float(row["rtol"]), float(row["atol"]), **store.row_options(row),
        )  # fmt: skip
    except (KeyError, TypeError, ValueError):
        return None
    return spec if spec.run_id == row.get("run_id") else None


OUTSIDE = "names files outside OUT and the folders given with --allow-root"


def named_paths(row: dict[str, Any]) -> list[str]:
    """The files and folders a row's problem options name (:data:`FILE_OPTIONS`)."""
    options = store.row_options(row)["problem_options"]
    paths = []
    for name in FILE_OPTIONS:
        value = options.get(name) or ()
        paths += [value] if isinstance(value, str) else [str(v) for v in value]
    return paths


def chosen_runs(
    out: Path,
    choose: Callable[[pd.DataFrame], pd.DataFrame] | None = None,
    allow_roots: Sequence[str | Path] = (),
) -> tuple[list[RunSpec], Counter]:
    """The runs of ``out`` to record (the rows ``choose`` keeps of a frame of all, see the
    module docstring) and why the others chosen are left out (reason -> count); a row may
    name files in ``out`` or below ``allow_roots``. ConfigError when ``out`` has no rows."""
    import pandas as pd

    rows, _broken = store.check_rows(out)
    if not rows:
        raise ConfigError(
            f"no result rows in {out}: give the output directory of a sweep "
            "(`workbench sweep --out OUT`)"
        )
    frame = pd.DataFrame(list(rows.values()))
    if choose is not None:
        frame = choose(frame)
    roots = [Path(root).resolve() for root in (out, *allow_roots)]

    def trusted(path: str) -> bool:  # resolved: a link cannot lead out
        return any(Path(out, path).resolve().is_relative_to(root) for root in roots)

    left_out: Counter = Counter()
    specs = []
    for row in frame.to_dict("records"):
        row = rows[row["run_id"]]  # as stored (filter_rows may have cast its values)
        if row.get("status") != "ok":
            left_out[f"status {row.get('status')}"] += 1
        elif not all(map(trusted, named_paths(row))):
            left_out[OUTSIDE] += 1
        elif stale_reason(row):
            left_out["stale (`workbench sweep --rerun stale` first)"] += 1
        elif (spec := spec_of_row(row)) is None:
            left_out["not made again from its row's keys"] += 1
        else:
            specs.append(spec)
    return specs, left_out


def record_runs(
    out: str | Path,
    recorder: Any,
    choose: Callable[[pd.DataFrame], pd.DataFrame] | None = None,
    jobs: int = 2,
    plugins: Sequence[str] = (),
    time_limit: float = DEFAULT_TIME_LIMIT,
    show_progress: bool = True,
    wait: bool = False,
    say: Callable[[str], None] | None = None,
    allow_roots: Sequence[str | Path] = (),
) -> RecordSummary:
    """Record the runs of ``out`` that ``choose`` keeps (module docstring; all without it)
    by running them again in ``jobs`` workers, rows kept, and merge their recordings into
    ``out``'s; ``recorder`` as :func:`workbench.runs.sweep.run_sweep` takes it (e.g.
    :class:`workbench.outputs.recording.SweepRecorder`); ``allow_roots``: folders outside
    ``out`` whose files the rows may name."""
    out_dir = Path(out)
    if jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, not {jobs}")
    if not out_dir.is_dir():
        raise ConfigError(f"no output directory {out_dir}: give the OUT of a sweep")
    with out_lock(out_dir, wait=wait, say=say):
        check_writable(out_dir)  # before the runs, not as each one's failure
        specs, left_out = chosen_runs(out_dir, choose, allow_roots)
        summary = RecordSummary(None, 0, left_out)
        if specs:
            timing = Timing(repeats=1, workers=jobs)  # the run's timing is its row's
            done: set[str] = set()
            with progress_bar("record", len(specs), show=show_progress, threaded=False) as bar:

                def recorded(run_id: str) -> None:
                    done.add(run_id)
                    bar.update(len(done))

                run_local(
                    [], out_dir, time_limit, list(plugins), jobs, lambda status: None,
                    bar.tick, recorder, timing, True, specs, recorded,
                )  # fmt: skip
            done -= unwritten_runs(out_dir)  # a worker killed before its file: not in it
            summary.recorded = len(done)
            summary.failed = [spec.run_id for spec in specs if spec.run_id not in done]
        summary.recording, _merged = merge_run_recordings(recorder, out_dir)
    return summary
