"""The performance benchmarks of docs/performance-targets.md in one command, and their summary.

Run: ``python -m benchmarks`` (runs benchmarks.default_sweep,
benchmarks.runner_throughput, benchmarks.overhead, benchmarks.peers and
benchmarks.simulation, then summarizes; about 17 minutes on 2 cores before the
random trees and robots joined (about 5 minutes more), most of it
compiling the 200-body models) or ``python -m benchmarks --summary`` (summarizes the
CSVs already in benchmarks/results/). The summary lists every target of the
Performance table (docs/performance-targets.md) that those CSVs measure, one line
each: the value, its interval where
the benchmark gives one (10-90 % of the interleaved repeats for forward dynamics, the
95 % bootstrap interval of the median for whole simulations), the target, and the
verdict: met, met at the median but not over the interval, missed by value / target,
or not measured (with the benchmark's reason, e.g. N = 500's Pinocchio memory).
Then the targets of issue 36, each with its figure or "not measured": forward dynamics
over processes from ``python -m benchmarks.peers_pyperf`` (the range over pairs of
processes; the verdict holds its upper end to the target) on two lines, each named: both
sides called from Python (``FastFunction.into`` against ``pin.aba``'s binding) and both
through the same CasADi buffer call into C (against ``pinocchio::aba``); beside them the same
timed in turn within each process (``python -m benchmarks.peers_paired``: the range of
the processes' ratios), the quick suite in the VM
against ``compile = "auto"`` from ``python -m benchmarks.compile_auto``, whole
simulations against the best Python-driven peer and the all-compiled anchor
(``benchmarks.anchor``: Pinocchio's C++ ABA under CasADi's CVODES; "not measured" with
the reason when it cannot be built here). Those two
benchmarks run alone (about 20 and 4 minutes on a busy machine), not in ``python -m
benchmarks``.
"""

from __future__ import annotations

import argparse
import sys
from typing import NamedTuple

import pandas as pd

from benchmarks import default_sweep, overhead, peers, runner_throughput, simulation

RESULTS = peers.RESULTS
NAN = float("nan")


def verdict(value: float, target: float, low: float = NAN, high: float = NAN, most=True) -> str:
    """'met' when the value (and its whole interval, if any) is on the right side of the
    target; 'met at the median, not over its interval' when only the value is; else
    'missed by' value / target (target / value for an at-least target). ``most``: the
    target is an upper bound (<=), else a lower bound (>=)."""
    if pd.isna(value):
        return "not measured"
    if pd.isna(target):
        return "measured (no target)"
    sign = 1 if most else -1
    within = sign * (value - target) <= 0
    worst = high if most else low
    if within and (pd.isna(worst) or sign * (worst - target) <= 0):
        return "met"
    if within:
        return f"met at the median, not over its interval (up to {worst:.2f})"
    return f"missed by {(value / target) ** sign:.2f}x"


class Row(NamedTuple):
    """One target of the issue as measured: ``low``, ``high`` its interval (NaN if none)."""

    target: str
    value: float
    bound: float
    most: bool = True
    low: float = NAN
    high: float = NAN
    interval: str = ""  # what the interval is
    note: str = ""


def targets() -> list[Row]:
    """Every target of docs/performance-targets.md that a CSV in RESULTS measures."""
    rows: list[Row] = []
    chains = RESULTS / "peers.csv"
    if chains.exists():
        spatial = pd.read_csv(chains).query("family == 'spatial'").set_index("N")
        if "jit/pin" in spatial:
            small = spatial.loc[spatial.index <= 50, "jit/pin"]
            rows.append(Row("spatial chain, jit / pin.aba, worst N <= 50", small.max(), 0.5,
                            note=f"N = {small.idxmax()}, best of 5"))  # fmt: skip
            if 200 in spatial.index:
                rows.append(Row("spatial chain, jit / pin.aba, N = 200",
                                spatial.loc[200, "jit/pin"], 1.0))  # fmt: skip
            rows.append(Row("spatial chain, vm / pin.aba, worst N", spatial["vm/pin"].max(), 5.0))
        if 50 in spatial.index:
            rows.append(Row("compile time, spatial chain N = 50 (s wall)",
                            spatial.loc[50, "compile_s"], 2.0,
                            note=f"load {spatial.loc[50, 'load1']:.1f}" if "load1" in spatial
                            else "wall time grows with the load; CPU below"))  # fmt: skip
            if "compile_cpu_s" in spatial:
                rows.append(Row("compile CPU time, spatial chain N = 50 (s, gcc included)",
                                spatial.loc[50, "compile_cpu_s"], 2.0,
                                note="one compile; peers.csv: the Zen 5, 2026-11-25"))  # fmt: skip
    rows += compile_rows()
    general = RESULTS / "peers_general.csv"
    if general.exists():
        for row in pd.read_csv(general).to_dict("records"):
            what = f"N = {row['name']}" if row["family"] == "random" else row["name"]
            big = row["family"] == "random" and row["N"] >= 200
            note = row.get("note")
            note = note if isinstance(note, str) else f"load {row['load1']:.1f}"
            rows.append(Row(
                f"forward dynamics, {row['family']} {what}, jit / pin.aba (CPU a call)",
                row["jit/pin"], 0.8 if big else 0.5, low=row["jit/pin_lo"],
                high=row["jit/pin_hi"], interval="10-90 %", note=note,
            ))  # fmt: skip
    sim = RESULTS / "simulation_targets.csv"
    if sim.exists():
        pairs = {"a": "same DOP853 both sides", "b": "best of ours / best peer"}
        for _, row in pd.read_csv(sim).query("pair in ('a', 'b')").iterrows():
            note = f"{row.ours} / {row.peer}; load {row.load_1min:.1f}" + _measured_on(row)
            if not pd.isna(row.get("floor", NAN)):
                note += (
                    f"; floor {row.floor:.2f} (only the rhs differing), "
                    f"{row.ratio_if_rhs_free:.2f} with a free rhs"
                )
            rows.append(Row(f"whole simulation, {row.case}, {pairs[row.pair]}", row.ratio,
                            row.target, low=row.low, high=row.high, interval="95 % CI",
                            note=note))  # fmt: skip
    for sweep in sorted(RESULTS.glob("default_sweep*.csv")):
        if "_stages" in sweep.name:
            continue
        row = pd.read_csv(sweep).iloc[0]
        suite = row.command.split()[2] if row.command.split()[2] != "--out" else "full"
        full = suite == "full"  # the targets were set for the full comparison
        load = f"load {row.load_1min:.1f}" if "load_1min" in row else ""
        if isinstance(row.get("cpu"), str):  # (measured before 2026-11-29: not recorded)
            load = f"{row.cpu}, {row.date}; {load}"
        what = f"sweep {suite} ({row.runs} runs)"
        rows.append(Row(f"{what}, peak memory of all processes (GiB)", row.peak_pss_gib,
                        1.0 if full else NAN, note=load))  # fmt: skip
        rows.append(Row(f"{what}, share of the runs' time outside the integrators",
                        row.outside_share_of_stages, 0.1 if full else NAN,
                        note=load if full else f"{load}; the target is the full sweep's: "
                        f"a quick run's {row.outside_per_run_ms:.0f} ms outside its "
                        f"integration is most of it"))  # fmt: skip
    dask = RESULTS / "dask_sweep.csv"
    if dask.exists():  # python -m benchmarks.dask_sweep: not part of `python -m benchmarks`
        row = pd.read_csv(dask).iloc[0]  # the first repeat (the docs say why)
        rows.append(Row("default sweep through a local 2-worker Dask cluster / local pool",
                        row.ratio, 1.3, note=f"{row.runs} runs, {row.dask_s:.0f} s against "
                        f"{row.local_s:.0f} s; load {row.load_1min:.1f}"))  # fmt: skip
    throughput = RESULTS / "runner_throughput_summary.csv"
    if throughput.exists():
        two = pd.read_csv(throughput).set_index("jobs").loc[2]
        rows.append(Row("200 short runs, 2 workers over 1 (best of 3)", two.speedup_best,
                        1.7, most=False, note=f"median {two.speedup_median:.2f}"))  # fmt: skip
    return rows


def _cache_fit_note() -> str:
    """What cachegrind's simulation of a 512 KiB L2 says (python -m benchmarks.cache_fit)."""
    path = RESULTS / "cache_fit.csv"
    if not path.exists():
        return "; run python -m benchmarks.cache_fit for a simulated 512 KiB L2"
    table = pd.read_csv(path)
    theirs = table.query("side == 'pinocchio::aba'").set_index("model").l2_misses_512K
    missing = table.query("side == 'ours' and l2_misses_512K >= 1")
    described = [
        f"{m.model} ({m.l2_misses_512K:.0f} a call, pinocchio::aba {theirs.get(m.model, NAN):.0f})"
        for m in missing.itertuples()
    ]
    fits = "all but " + ", ".join(described) if described else "every model"
    return (
        f"; simulated (cachegrind, cache_fit.csv): with a 512 KiB L2 {fits} "
        "called without L2 misses in steady state"
    )


def _code_note(row: dict) -> str:
    """The compiled graph (unrolled or joint-type kernels) and its size in C (bytes: a
    load-independent figure), when the CSV has them."""
    if "graph" not in row or "code_bytes" not in row:
        return ""
    return f"; {row['graph']}, {row['code_bytes'] / 1e6:.2f} MB of C"


def issue35_targets() -> list[Row]:
    """The targets of issue 35 as ``python -m benchmarks.footprint --targets`` measured them
    (``footprint-targets.csv``: its own limits and verdicts, one line each)."""
    targets = RESULTS / "footprint-targets.csv"
    if not targets.exists():
        return [Row("footprint (issue 35)", NAN, NAN,
                    note="run python -m benchmarks.footprint --targets")]  # fmt: skip
    newer = {}  # a later measurement of one target alone (--tiny) replaces the --targets one
    unrecorded = []  # the same measure under --no-recording: said, not the target's
    tiny = RESULTS / "footprint-tiny.csv"
    if tiny.exists():
        measured = pd.read_csv(tiny).dropna(subset=["marginal_outside_cpu_ms"])
        for code in ("after", "after, no recording"):
            last = measured[measured["code"] == code]
            if not len(last):
                continue
            row = last.iloc[-1]
            cpu = f"{row.cpu}; " if isinstance(row.get("cpu"), str) else ""
            note = (
                f"{cpu}load {row.load_1min:.1f}; integration {row.integration_cpu_ms:.1f} ms a "
                "run; footprint-tiny.csv"
            )
            if code == "after":
                name = "time outside integration, marginal at 10,000 runs"
                newer[name] = (row.marginal_outside_cpu_ms, note)
            else:
                name = f"  the same with sweep --no-recording, at {int(row.n):,} runs (ms)"
                unrecorded.append(Row(name, row.marginal_outside_cpu_ms, NAN, note=note))
    read = readback_rows()  # the reader on the default sweep's recording, measured alone
    rows = []
    for row in pd.read_csv(targets).itertuples():
        name = row.target.strip()
        if read and name.startswith("Python reader"):
            rows.extend(read)
            read = []
            continue
        unit = row.unit if isinstance(row.unit, str) else ""
        value, note = newer.get(name, (row.measured, f"load {row.load_1min:.1f}"))
        rows.append(Row(f"{name} ({unit})" if unit else name, value, row.limit,
                        note=note))  # fmt: skip
        if name in newer:
            rows += unrecorded
    return rows


def readback_rows() -> list[Row]:
    """Python's reader on the default sweep's recording as ``python -m benchmarks.footprint
    --read-back`` measured it last (``footprint-readback.csv``, its "after" row): growth
    cold and beyond the reader's start-up, each against 2x the file."""
    measured = RESULTS / "footprint-readback.csv"
    if not measured.exists():
        return []
    after = pd.read_csv(measured).query("code == 'after'")
    if after.empty:
        return []
    row = after.iloc[-1]
    note = (f"{row.size_mib:.2f} MiB file, {row.runs:.0f} runs; load {row.load_1min:.1f}; "
            "footprint-readback.csv")  # fmt: skip
    limit = 2 * row.size_mib
    return [
        Row("Python reader: peak growth, cold (MiB)", row.read_growth_mib, limit, note=note),
        Row("Python reader: growth beyond its start-up (MiB)", row.read_beyond_startup_mib,
            limit, note=f"start-up {row.reader_startup_mib:.1f} MiB; " + note),
    ]  # fmt: skip


def issue36_targets() -> list[Row]:
    """The targets of issue 36, each measured or "not measured" (the reason in its note)."""
    rows: list[Row] = []
    # python -m benchmarks.peers_pyperf: one file a machine (named by its L2), each alike
    machines = sorted(RESULTS.glob("peers_pyperf*.csv"),
                      key=lambda path: -pd.read_csv(path)["l2_kib"].iloc[0])  # fmt: skip
    missed, worst = [], 0.0
    for timed in machines:
        for row in pd.read_csv(timed).to_dict("records"):
            what = f"random tree N = {row['name']}" if row["kind"] == "random" else row["name"]
            bound = 0.3 if row["kind"] == "robots" else 0.8 if int(row["name"]) >= 200 else 0.5
            machine = f"{row['cpu']}, L2 {row['l2_kib']} KiB a core"
            machine += f", {row['date']}" if isinstance(row.get("date"), str) else ""
            lines = [("", "jit / pin.aba, both called from Python")]
            if "buffer_ratio_max" in row:  # the like-for-like line in C (benchmarks/aba_call.cpp)
                lines.append(("buffer_", "jit / pinocchio::aba, both through CasADi's buffer call"))
            for prefix, line in lines:
                rows.append(Row(
                    f"forward dynamics, {what}, {line} (pyperf, CPU; L2 {row['l2_kib']} KiB)",
                    row[f"{prefix}ratio_median"], bound, low=row[f"{prefix}ratio_min"],
                    high=row[f"{prefix}ratio_max"],
                    interval=f"all pairs of {row['processes']} processes"
                    + (", each its own copy of the libraries" if "copies" in row else ""),
                    note=f"{machine}; held to the upper end; {row[f'{prefix}ours_us']:.2f} / "
                    f"{row[f'{prefix}pin_aba_us']:.2f} us; load {row['load1_before']:.1f}-"
                    f"{row['load1_after']:.1f}" + _code_note(row)
                    + (f"; ours by the {row['python_call']} call"
                       if not prefix and "python_call" in row else ""),
                ))  # fmt: skip
                worst = max(worst, row[f"{prefix}ratio_max"] / bound)
                if not row[f"{prefix}ratio_max"] <= bound:
                    where = "in C" if prefix else "from Python"
                    missed.append(f"{what} {where} (L2 {row['l2_kib']} KiB)")
    rows += paired_rows()
    if not machines:
        rows.append(Row("forward dynamics vs pin.aba over processes (pyperf)", NAN, 0.5,
                        note="run python -m benchmarks.peers_pyperf"))  # fmt: skip
    else:  # the issue asks for any machine: the worst of all machines measured
        rows.append(Row(f"the same on every machine measured ({len(machines)}, each its own "
                        "cache): the worst upper end over its target", worst, 1.0,
                        note=f"missed: {', '.join(missed) or 'none'}"
                        + _cache_fit_note()))  # fmt: skip
    auto = RESULTS / "compile_auto.csv"  # python -m benchmarks.compile_auto
    if auto.exists():
        table = pd.read_csv(auto).set_index("variant")
        none, cold, warm = (table.loc[v] for v in ("none", "auto cold", "auto warm"))
        load = f"load {cold.get('load1_before', NAN):.0f}-{warm.get('load1_after', NAN):.0f}"
        rows.append(Row("quick sweep, integration CPU, compile=auto (warm) / none",
                        warm.integrate_cpu_s / none.integrate_cpu_s, NAN,
                        note=f"{warm.integrate_cpu_s:.1f} s / {none.integrate_cpu_s:.1f} s over "
                        f"{int(none.ok_in_all)} runs; {load}"))  # fmt: skip
        if not pd.isna(cold.get("cpu_s", NAN)):
            rows.append(Row("quick sweep, CPU of all processes, auto cold / none",
                            cold.cpu_s / none.cpu_s, NAN,
                            note=f"cold {cold.cpu_s:.0f} s, warm {warm.cpu_s:.0f} s, "
                            f"none {none.cpu_s:.0f} s"))  # fmt: skip
    else:
        rows.append(Row("quick sweep, integration CPU, compile=auto / none", NAN, NAN,
                        note="run python -m benchmarks.compile_auto"))  # fmt: skip
    sim = RESULTS / "simulation_targets.csv"  # python -m benchmarks.simulation
    all_pairs = pd.read_csv(sim) if sim.exists() else pd.DataFrame(columns=["case", "pair"])
    best = all_pairs.query("pair == 'b'")
    for case in ("chain", "tree", "ur5"):
        found = best[best["case"] == case] if len(best) else best
        if len(found):
            row = found.iloc[0]
            note = f"{row.ours} / {row.peer}; load {row.load_1min:.1f}" + _measured_on(row)
            walls = RESULTS / "simulation.csv"
            if walls.exists():  # how near the all-compiled anchor itself comes to the target
                table = pd.read_csv(walls).query("case == @case").set_index("pipeline")
                if "anchor" in set(table.side):
                    anchor = table[table.side == "anchor"].wall_s.min()
                    note += f"; the anchor / that peer {anchor / table.wall_s[row.peer]:.2f}"
            calls = getattr(row, "rhs_calls_ours_side", NAN)
            if not pd.isna(calls):  # where the time goes: calls x (wall a call)
                note += (
                    f"; rhs calls {calls:.0f} / {row.rhs_calls_peer_side:.0f}, "
                    f"us a call {row.us_per_rhs_ours_side:.1f} / {row.us_per_rhs_peer_side:.1f}"
                )
            rows.append(Row(f"whole simulation, {case}, best of ours / best Python-driven peer",
                            row.ratio, 0.5, low=row.low, high=row.high, interval="95 % CI",
                            note=note))  # fmt: skip
        else:
            rows.append(Row(f"whole simulation, {case}, best of ours / best peer", NAN, 0.5,
                            note="run python -m benchmarks.simulation"))  # fmt: skip
        anchor = all_pairs[(all_pairs["case"] == case) & (all_pairs["pair"] == "c")]
        if len(anchor):
            row = anchor.iloc[0]
            note = row.note if isinstance(row.get("note"), str) and row.note else ""
            note = note or f"{row.ours} / {row.peer}; load {row.load_1min:.1f}"
            note += _measured_on(row)
            rows.append(Row(f"whole simulation, {case}, best of ours / all-compiled anchor",
                            row.ratio, 1.5, low=row.low, high=row.high, interval="95 % CI",
                            note=note))  # fmt: skip
        else:
            rows.append(Row(f"whole simulation, {case}, ours / all-compiled anchor", NAN, 1.5,
                            note="run python -m benchmarks.simulation"))  # fmt: skip
    return rows


def _measured_on(row: pd.Series) -> str:
    """'; <cpu>, <date>' of a benchmark's row where it names them (older files do not)."""
    where = [str(row[k]) for k in ("cpu", "date") if isinstance(row.get(k), str)]
    return "; " + ", ".join(where) if where else ""


def compile_rows() -> list[Row]:
    """The N = 50 chain's cold compiles (``python -m benchmarks.compile_time``), a line a
    machine: the median CPU seconds and their range."""
    table = RESULTS / "compile_time.csv"
    if not table.exists():
        return []
    rows = []
    for (model, cpu, l2), group in pd.read_csv(table).groupby(["model", "cpu", "l2_kib"]):
        seconds = group["compile_cpu_s"]
        loads = pd.concat([group["load1_before"], group["load1_after"]])
        rows.append(Row(
            f"compile CPU time, {model}, cold (s, gcc included; L2 {l2} KiB)",
            float(seconds.median()), 2.0, low=float(seconds.min()), high=float(seconds.max()),
            interval=f"{len(group)} compiles",
            note=f"{cpu}, {', '.join(sorted(set(group['date'])))}; load "
            f"{loads.min():.1f}-{loads.max():.1f}",
        ))  # fmt: skip
    return rows


def paired_rows() -> list[Row]:
    """Issue 36's per-call targets as ``python -m benchmarks.peers_paired`` measures them:
    both sides timed in turn within each process, the ratio's range over processes (its
    upper end the worst process), with pyperf's statistic from the same timings in the
    note. Beside the pyperf lines, not instead of them."""
    rows = []
    for timed in sorted(RESULTS.glob("peers_paired*.csv")):
        for row in pd.read_csv(timed).to_dict("records"):
            what = f"random tree N = {row['name']}" if row["kind"] == "random" else row["name"]
            bound = 0.3 if row["kind"] == "robots" else 0.8 if int(row["name"]) >= 200 else 0.5
            for prefix, line in (("", "from Python"), ("buffer_", "in C")):
                rows.append(Row(
                    f"forward dynamics, {what}, {line}, both timed in turn in each process "
                    f"(peers_paired; L2 {row['l2_kib']} KiB)",
                    row[f"{prefix}paired_median"], bound, low=row[f"{prefix}paired_min"],
                    high=row[f"{prefix}paired_max"],
                    interval=f"{row['processes']} processes' ratios",
                    note=f"{row['cpu']}; held to the worst process; "
                    f"{row[f'{prefix}ours_us']:.2f} / {row[f'{prefix}pin_aba_us']:.2f} us; the "
                    f"slowest process of ours / the fastest of Pinocchio's "
                    f"{row[f'{prefix}crossed_max']:.2f}; load {row['load1_before']:.1f}-"
                    f"{row['load1_after']:.1f}",
                ))  # fmt: skip
    return rows


def print_rows(rows: list[Row]) -> None:
    for row in rows:
        interval = ""
        if not (pd.isna(row.low) or pd.isna(row.high)):
            interval = f" [{row.low:.2f}, {row.high:.2f}] ({row.interval})"
        bound = "none" if pd.isna(row.bound) else f"{'<=' if row.most else '>='} {row.bound:g}"
        value = "n/a" if pd.isna(row.value) else f"{row.value:.2f}"
        if value == f"{row.bound:.2f}" and row.value != row.bound:  # 0.102 is not 0.10
            value = f"{row.value:.3f}"
        line = f"- {row.target}: {value}{interval}, target {bound}: "
        line += verdict(row.value, row.bound, row.low, row.high, row.most)
        print(line + (f" ({row.note})" if row.note else ""))


def summary() -> None:
    rows = targets()
    if not rows:
        print(f"no results in {RESULTS}: run `python -m benchmarks` first")
    else:
        print("issue targets (value [interval]; verdict):")
        print_rows(rows)
    print("issue 35 targets (footprint; value, target, verdict):")
    print_rows(issue35_targets())
    print("issue 36 targets (value [interval]; verdict):")
    print_rows(issue36_targets())
    calls = RESULTS / "overhead.csv"
    if calls.exists():
        frame = pd.read_csv(calls)
        print("FastFunction.into overhead per call (us):", frame.overhead_us.round(2).tolist())


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    parser.add_argument("--summary", action="store_true", help="only summarize the CSVs")
    args = parser.parse_args(argv)
    if not args.summary:
        default_sweep.main([])
        runner_throughput.main([])
        overhead.main([])
        peers.main([])
        simulation.main([])
    summary()


if __name__ == "__main__":
    main(sys.argv[1:])
