"""A sweep in the CasADi VM against ``compile = "auto"``, cold and warm (issue 36, item 2).

Run: ``python -m benchmarks.compile_auto [--suite quick] [--time-limit 30]``. Three sweeps
of the suite, each a fresh ``workbench sweep`` process: every formalism with ``compile =
"none"`` (the sweep's default before), then with the default ``"auto"`` twice over the
same compile cache, first empty (cold) then filled by the first (warm). For each: wall
and CPU time of all its processes (the C compiler included), the sum of the runs'
integration CPU (``integrate_cpu_s``, over the runs ok in all three), of their
``compile_s`` (wall) and how many rows ran some function in C. Writes
``benchmarks/results/compile_auto.csv``; ``--analyze NONE COLD WARM`` summarizes three
existing sweep directories instead (wall and CPU then unknown).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

RESULTS = Path(__file__).parent / "results"
VARIANTS = ("none", "auto cold", "auto warm")


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def sweep(spec: str, out: Path, cache: Path, time_limit: float) -> dict:
    """One ``workbench sweep`` in a fresh process: wall, CPU (all processes) and loads."""
    env = {**os.environ, "WORKBENCH_CACHE": str(cache)}
    command = [sys.executable, "-m", "workbench", "sweep", spec, "--out", str(out),
               "--time-limit", str(time_limit)]  # fmt: skip
    load, start, cpu = os.getloadavg()[0], time.perf_counter(), children_cpu()
    subprocess.run(command, env=env, check=True, stdout=subprocess.DEVNULL)
    return {"wall_s": time.perf_counter() - start, "cpu_s": children_cpu() - cpu,
            "load1_before": load, "load1_after": os.getloadavg()[0]}  # fmt: skip


def analyze(directories: list[Path], measured: list[dict] | None = None) -> pd.DataFrame:
    """One row a variant: sums over the runs ok in every variant (same keys)."""
    key = ["problem", "formalism", "integrator", "rtol"]
    frames = [pd.read_parquet(d / "results.parquet") for d in directories]
    common = None
    for frame in frames:
        ok = set(map(tuple, frame.loc[frame.status == "ok", key].to_numpy()))
        common = ok if common is None else common & ok
    rows = []
    for variant, frame, extra in zip(VARIANTS, frames, measured or [{}] * 3, strict=True):
        mine = frame[[tuple(k) in common for k in frame[key].to_numpy()]]
        notes = mine["notes"].fillna("")
        rows.append({
            "variant": variant, "runs": len(frame), "ok_in_all": len(mine),
            "integrate_cpu_s": mine.integrate_cpu_s.sum(), "compile_s": frame.compile_s.sum(),
            "rows_with_c": int(notes.str.contains("compile=auto: in C").sum()),
            "cpu_s_rows": frame.cpu_s.sum(), **extra,
        })  # fmt: skip
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.compile_auto", description=__doc__)
    parser.add_argument("--suite", default="quick")
    parser.add_argument("--time-limit", type=float, default=30.0)
    parser.add_argument("--analyze", nargs=3, type=Path, metavar=("NONE", "COLD", "WARM"))
    parser.add_argument("--keep", type=Path, help="keep the three sweeps in this directory")
    args = parser.parse_args(argv)
    if args.analyze:
        table = analyze(args.analyze)
    else:
        from workbench.runs.sweep_spec import suite_text

        with tempfile.TemporaryDirectory() as work:
            work_dir = args.keep or Path(work)
            work_dir.mkdir(parents=True, exist_ok=True)
            vm_spec = work_dir / "vm.toml"
            vm_options = 'options = { index = 1, compile = "none" }'
            text = suite_text(args.suite).replace("options = { index = 1 }", vm_options)
            if 'compile = "none"' not in text:
                raise SystemExit(f"suite {args.suite}: no formalism options to set compile in")
            vm_spec.write_text(text)
            specs = (str(vm_spec), args.suite, args.suite)
            caches = (work_dir / "cache-vm", work_dir / "cache", work_dir / "cache")
            outs = [work_dir / name.replace(" ", "-") for name in VARIANTS]
            measured = [sweep(s, o, c, args.time_limit)
                        for s, o, c in zip(specs, outs, caches, strict=True)]  # fmt: skip
            table = analyze(outs, measured)
        RESULTS.mkdir(exist_ok=True)
        table.to_csv(RESULTS / "compile_auto.csv", index=False)
    with pd.option_context("display.width", 200):
        print(table.to_string(index=False, float_format="{:.3g}".format))
    return table


if __name__ == "__main__":
    main()
