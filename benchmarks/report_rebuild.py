"""A report written again, problem by problem (issue 35.3): the quick suite's report
drawn from nothing, then again with nothing changed, then after the sweep redid some
runs of one problem.

Run: ``python -m benchmarks.report_rebuild [--rounds 2]`` (about 4 min on 2 cores). Runs
the quick suite once (``workbench sweep --no-report``, 2 workers, 1 timed sample), then
each round: ``workbench report OUT --out R`` into a new folder R ("from nothing"), again
into R ("nothing changed"), then ``workbench sweep --rerun timeout --retime 0
--no-report`` (the quick suite's two timeouts, runs of one problem, redone; without
``--retime 0`` the sweep would also time its close calls again, changing the rows of the
problems that have one) and the report into R again ("one problem's runs redone"; the
column ``problems_drawn`` counts the sections drawn). A report's CPU: its process and
children (``RUSAGE_CHILDREN``). Prints the table and the load; writes
``benchmarks/results/report_rebuild.csv``.
"""

from __future__ import annotations

import argparse
import datetime
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from workbench.execution.environment import cpu_model
from workbench.outputs.report.section_cache import SUFFIX

RESULTS = Path(__file__).parent / "results"
WORKBENCH = [sys.executable, "-m", "workbench"]


def timed(command: list[str]) -> dict[str, float]:
    """Wall and CPU seconds of ``command`` (its children included)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    return {"wall_s": time.perf_counter() - start, "cpu_s": cpu}


def drawn_since(report: Path, moment: float) -> int:
    """Problems whose section was described (drawn) after ``moment`` (a time.time())."""
    return sum(p.stat().st_mtime > moment for p in (report / "figures").glob(f"*{SUFFIX}"))


def rebuild_rows(rounds: int) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as directory:
        out = Path(directory) / "quick"
        subprocess.run([*WORKBENCH, "sweep", "--out", str(out), "--no-report", "--repeats", "1"],
                       check=True, capture_output=True)  # fmt: skip
        for index in range(rounds):
            report = Path(directory) / f"report-{index}"
            command = [*WORKBENCH, "report", str(out), "--out", str(report)]
            for case in ("from nothing", "nothing changed", "one problem's runs redone"):
                if case == "one problem's runs redone":
                    subprocess.run([*WORKBENCH, "sweep", "--out", str(out), "--rerun", "timeout",
                                    "--retime", "0", "--no-report", "--repeats", "1"],
                                   check=True, capture_output=True)  # fmt: skip
                moment = time.time()
                measured = timed(command)
                row = {"round": index + 1, "case": case, **measured,
                       "problems_drawn": drawn_since(report, moment),
                       "load_1min": os.getloadavg()[0]}  # fmt: skip
                rows.append(row)
                print(row, flush=True)
    for row in rows:
        row |= {"cpu": cpu_model(), "date": datetime.date.today().isoformat()}
    return rows


def main(argv: list[str] | None = None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.report_rebuild",
                                     description=__doc__)  # fmt: skip
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args(argv)
    print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    table = pd.DataFrame(rebuild_rows(args.rounds))
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "report_rebuild.csv", index=False)
    print(table.drop(columns=["cpu", "date"]).round(2).to_string(index=False))
    return table


if __name__ == "__main__":
    main()
