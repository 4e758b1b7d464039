"""Whole simulations against Pinocchio and MuJoCo at the same end accuracy (issue 21, target 2).

Run: ``python -m benchmarks.simulation [--repeat 21] [--cases chain tree ur5]``. The cases are
those of :mod:`benchmarks.simulation_models` (7-link spatial chain over 2 s, a random
30-body revolute tree over 2 s, the UR5 from its URDF over 1 s); before any timing,
Pinocchio's and MuJoCo's accelerations are checked equal to ours (1e-9 relative).

Pipelines (all integrate from the same y0 to t_end; 51 output times where they offer them):

- ours: the ``recursive`` formalism compiled to C (``compile = "jit"``), through our
  integrator plugins exactly as a run calls them (``Integrator.solve``): ``scipy-dop853``,
  ``sundials-cvode-adams``, ``casadi-cvodes`` and ``sundials-cvode-c`` (both Adams with
  fixed-point iteration; the latter SUNDIALS CVODE driven from C on the generated
  right-hand side, no CasADi between steps) and ``heyoka-taylor`` (its LLVM compilation,
  done again by every solve, is excluded like our C compilation: wall minus ``setup_s``);
- peers: SciPy DOP853 calling ``pin.aba``; SUNDIALS CVODE (Adams and BDF, scikit-sundae)
  calling ``pin.aba``; MuJoCo's RK4 in C (``opt.integrator = RK4``, fixed step, stepped by
  ``mujoco.rollout`` so no Python runs between steps);
- the all-compiled anchors (:mod:`benchmarks.anchor`): Pinocchio's C++ ABA as a CasADi
  external function under CasADi's CVODES (Adams, fixed-point iteration, as ours), the
  integrator built once per tolerance, so a round times only C (CVODES calling C++); and
  the same function under SUNDIALS CVODE driven from C (the ``sundials-cvode-c`` driver,
  Adams, fixed-point iteration), with no CasADi between steps. Pair (c) takes the faster. Its
  accelerations are checked equal to ours before any timing, and its end state must
  match the reference like any pipeline's (the ladder below), or the benchmark stops.

Accuracy: ``end_error`` is the largest difference of the final (q, v) from a reference
(DOP853 at rtol = atol = 1e-13 on our compiled right-hand side). The target accuracy is
that of DOP853 + ``pin.aba`` at rtol 1e-8, atol 1e-10. Pair (a) runs both DOP853 sides at
that tolerance. For pair (b) every pipeline is run at the loosest setting of its ladder
(rtol 1e-6, 3.16e-7, 1e-7 ... 1e-12, half decades, with atol = rtol / 100; MuJoCo: steps
2^k x 256) whose end error is at most 1.5 x the target (the ``setting`` column).

Where the time goes: each pipeline's ``steps`` and ``rhs_calls`` (from its own statistics,
read after the solve, never counted inside it; NaN where it reports none: SciPy and
scikit-sundae give only calls; scikit-sundae's CVODE iterates by Newton with a difference-
quotient Jacobian, whose 2n calls a Jacobian are counted too) and ``us_per_rhs`` = median
wall / rhs calls, everything included (the integrator's own work a call); the pairs' rows
repeat both sides' figures (``rhs_calls_ours_side`` ...).

Timing: ``--repeat`` rounds; each round runs every pipeline once, in a shuffled order
(interleaved, so a change of the machine's load falls on all of them). ``wall_s`` is the
median over rounds; a ratio is computed round by round (ours / peer in the same round)
and reported as its median and a 95 % bootstrap interval of that median. Pair (a): ours
DOP853 / DOP853 + pin.aba (target <= 0.8); pair (b): the best of ours / the best peer,
each side's best chosen by median wall (target <= 0.5); pair (c): the best of ours / the
faster anchor (target <= 1.5; NaN with the reason in ``note`` when the anchor cannot be built,
e.g. no C++ compiler). ``best_ratio``, the ratio of
the two pipelines' fastest rounds, is given beside it: on a loaded machine the fastest
round is the one least disturbed.

Why pair (a) is what it is (:func:`rhs_split`): after the rounds, 9 more DOP853 solves a
side with the right-hand side timed inside ``solve_ivp`` (:class:`RhsClock`) give SciPy's
own seconds and the right-hand side's, ours and the peer's; ``floor`` = (own + rhs ours) /
(own + rhs peer) is the ratio when only the right-hand sides differ, and
``ratio_if_rhs_free`` = own / (own + rhs peer) the least ratio any right-hand side of ours
could give under SciPy. Prints the table and the verdicts, writes
``benchmarks/results/simulation.csv`` (every pipeline) and
``benchmarks/results/simulation_targets.csv`` (the two ratios per case, with machine load,
and the split of pair (a); NaN for pair (b), where it is not measured).
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from unittest import mock

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp
from scipy.stats import bootstrap

from benchmarks.anchor import Anchor, AnchorUnavailable
from benchmarks.simulation_models import CASES, TOLERANCE, Case, Peers, case, check_equal
from workbench.execution.environment import cpu_model
from workbench.plugin.registry import get_formalism, get_integrator
from workbench.plugins.integrators import scipy_ivp

RESULTS = Path(__file__).parent / "results"
TARGET_RTOL, TARGET_ATOL = 1e-8, 1e-10
SLACK = 1.5  # a pipeline matches when its end error is <= SLACK x the target's
# half decades: a pipeline's setting is within a factor 3.2 of the loosest that matches (with
# whole decades the chain's CVODES took rtol 1e-11 for an end error 1.2x the allowed at 1e-10)
LADDER = tuple(float(f"{r:.3g}") for r in np.logspace(-6, -12, 13))
MUJOCO_STEPS = tuple(256 * 2**k for k in range(13))
OURS = {
    "scipy-dop853": None,
    "sundials-cvode-adams": None,
    "casadi-cvodes": {"method": "adams", "iteration": "functional"},
    "sundials-cvode-c": {"method": "adams", "iteration": "functional"},
    "heyoka-taylor": None,
}
TARGETS = {"a": 0.8, "b": 0.5, "c": 1.5}
ANCHOR = "anchor: CVODES Adams (CasADi) + pinocchio::aba (C++)"
ANCHOR_C = "anchor: CVODE Adams (C driver) + pinocchio::aba (C++)"
ANCHORS = (ANCHOR, ANCHOR_C)
NAN = float("nan")
SPLIT_ROUNDS = 9  # instrumented DOP853 runs a side for the split of pair (a)


def interval(ratios: np.ndarray) -> tuple[float, float, float]:
    """(median, low, high): the median of the per-round ratios and its 95 % bootstrap interval."""
    median = float(np.median(ratios))
    if ratios.size < 3 or np.ptp(ratios) == 0:
        return median, float(ratios.min()), float(ratios.max())
    result = bootstrap(
        (ratios,), np.median, confidence_level=0.95, method="percentile", random_state=0
    )
    return median, float(result.confidence_interval.low), float(result.confidence_interval.high)


class Pipelines:
    """The pipelines of one case: each ``run(setting)`` integrates and returns (final y,
    seconds to subtract from the wall time, (steps, right-hand-side calls)); a count the
    pipeline does not report is NaN (read after the solve, never counted inside it)."""

    def __init__(self, bench: Case) -> None:
        self.case = bench
        self.equations = get_formalism("recursive")().build(bench.model, {"compile": "jit"})
        start = time.perf_counter()
        self.equations.forms["ode"].rhs.compile()
        self.compile_s = time.perf_counter() - start
        self.n = bench.y0.size // 2
        self.times = np.linspace(0.0, bench.t_end, 51)
        self.peers = Peers(bench)
        rhs = self.equations.forms["ode"].rhs
        self.max_rel_diff = check_equal(
            lambda q, v: rhs(0.0, np.concatenate([q, v]))[0][self.n :], self.peers, self.n
        )
        self.anchor: Anchor | None = None
        self.anchor_note = ""
        try:
            self.anchor = Anchor(*bench.pin, bench.y0, self.times)
        except AnchorUnavailable as error:
            self.anchor_note = f"not measured: {error}"
        if self.anchor is not None:  # the C++ side against ours, like the peers
            check = np.random.default_rng(7)
            for _ in range(3):
                q, v = check.uniform(-2, 2, self.n), check.uniform(-2, 2, self.n)
                ours = rhs(0.0, np.concatenate([q, v]))[0][self.n :]
                difference = np.abs(self.anchor.accelerations(q, v) - ours).max()
                if not difference <= TOLERANCE * max(1.0, float(np.abs(ours).max())):
                    raise AssertionError(f"the anchor's aba differs from ours by {difference:.2e}")

    def ours(self, name: str, options: dict | None) -> Callable[[float], tuple]:
        integrator = get_integrator(name)()

        def run(rtol: float) -> tuple:
            trajectory = integrator.solve(
                self.equations, self.case.y0, None, self.times, rtol, rtol / 100, options, "ode"
            )
            if not trajectory.success:
                raise RuntimeError(f"{name}: {trajectory.message}")
            stats = trajectory.stats
            setup = stats.setup_s if name == "heyoka-taylor" else 0.0
            counts = (stats.n_steps or NAN, stats.n_rhs or NAN)
            return np.asarray(trajectory.y)[-1], float(setup or 0.0), counts

        return run

    def pin_rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        return np.concatenate([y[self.n :], self.peers.aba(y[: self.n], y[self.n :])])

    def pin_dop853(self, rtol: float, solver: Callable = solve_ivp) -> tuple:
        solution = solver(
            self.pin_rhs, (0.0, self.case.t_end), self.case.y0, method="DOP853",
            t_eval=self.times, rtol=rtol, atol=rtol / 100,
        )  # fmt: skip
        return solution.y[:, -1], 0.0, (NAN, float(solution.nfev))

    def pin_cvode(self, method: str) -> Callable[[float], tuple]:
        from sksundae.cvode import CVODE

        n = self.n

        def rhsfn(t: float, y: np.ndarray, yp: np.ndarray) -> None:
            yp[:n] = y[n:]
            yp[n:] = self.peers.aba(y[:n], y[n:])

        def run(rtol: float) -> tuple:
            solver = CVODE(rhsfn, method=method, rtol=rtol, atol=rtol / 100, max_num_steps=100000)
            result = solver.solve(self.times, self.case.y0)
            if not result.success:
                raise RuntimeError(f"CVODE {method} + pin.aba: {result.message}")
            # Newton iteration with a difference-quotient Jacobian: SUNDIALS counts its 2n
            # right-hand sides a Jacobian apart from nfev
            calls = float(result.nfev + 2 * n * result.njev)
            return np.asarray(result.y)[-1], 0.0, (NAN, calls)

        return run

    def mujoco_rk4(self, steps: int) -> tuple:
        import mujoco
        from mujoco import rollout

        model, order = self.case.mujoco
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
        model.opt.timestep = self.case.t_end / steps
        data = mujoco.MjData(model)
        data.qpos[:], data.qvel[:] = self.case.y0[: self.n][order], self.case.y0[self.n :][order]
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        state = np.empty(mujoco.mj_stateSize(model, spec))
        mujoco.mj_getState(model, data, state, spec)
        trajectory, _ = rollout.rollout(model, data, state[None, :], nstep=steps)
        final = trajectory[0, -1]
        back, nq = np.argsort(order), model.nq
        final = np.concatenate([final[1 : 1 + nq][back], final[1 + nq : 1 + 2 * nq][back]])
        return final, 0.0, (float(steps), 4.0 * steps)  # RK4: 4 forward dynamics a step


class RhsClock:
    """``solve_ivp`` with its right-hand side timed, to split a DOP853 solve into the time
    inside the right-hand side and SciPy's own (per-step Python and NumPy) work.

    ``calls``, ``inside`` (s in the rhs) and ``total`` (s in the solves) are summed;
    :meth:`split` removes the clock's own cost a call, ``cost`` = (s counted inside,
    s added outside) as :func:`clock_cost` measures it on an empty function."""

    def __init__(self, cost: tuple[float, float] = (0.0, 0.0)) -> None:
        self.calls, self.inside, self.total = 0, 0.0, 0.0
        self.cost = cost

    def wrap(self, fun: Callable) -> Callable:
        clock = time.perf_counter

        def timed(t: float, y: np.ndarray) -> np.ndarray:
            start = clock()
            value = fun(t, y)
            self.inside += clock() - start
            self.calls += 1
            return value

        return timed

    def solve_ivp(self, fun: Callable, *args, **kwargs):  # noqa: ANN201 - SciPy's result
        start = time.perf_counter()
        try:
            return solve_ivp(self.wrap(fun), *args, **kwargs)
        finally:
            self.total += time.perf_counter() - start

    def split(self) -> tuple[float, float, int]:
        """(SciPy's own s, rhs s, rhs calls) summed over the solves, clock cost removed."""
        cost_in, cost_out = self.cost
        inside = self.inside - self.calls * cost_in
        own = self.total - self.inside - self.calls * cost_out
        return own, inside, self.calls


def clock_cost(n: int = 50_000) -> tuple[float, float]:
    """(s a call that :class:`RhsClock` counts inside the rhs, s a call it adds outside),
    from an empty function: the best of 5."""
    y, bare = np.zeros(2), lambda t, y: y
    results = []
    for _ in range(5):
        probe = RhsClock()
        timed = probe.wrap(bare)
        start = time.perf_counter()
        for _ in range(n):
            bare(0.0, y)
        plain = time.perf_counter() - start
        start = time.perf_counter()
        for _ in range(n):
            timed(0.0, y)
        wrapped = time.perf_counter() - start
        cost_in = probe.inside / n
        results.append((cost_in, max(0.0, (wrapped - plain) / n - cost_in)))
    return min(results, key=sum)


def rhs_split(pipelines: Pipelines, ours: Callable, rounds: int) -> dict[str, float]:
    """Pair (a) taken apart: medians over ``rounds`` instrumented solves a side
    (interleaved, apart from the timed rounds) of SciPy's own seconds and the right-hand
    side's, ours (the scipy-dop853 plugin's rhs, its wrapper included) and DOP853 +
    pin.aba. ``floor`` = (own + rhs ours) / (own + rhs peer), ``own`` the mean of the two
    sides' own time: the ratio when only the right-hand sides differ.
    ``ratio_if_rhs_free`` = own / (own + rhs peer): the least ratio a right-hand side of
    ours costing nothing could give under SciPy's DOP853."""
    cost = clock_cost()
    parts: dict[str, list[tuple[float, float, int]]] = {"ours": [], "peer": []}
    for _ in range(rounds):
        clock = RhsClock(cost)
        with mock.patch.object(scipy_ivp, "solve_ivp", clock.solve_ivp):
            ours(TARGET_RTOL)
        parts["ours"].append(clock.split())
        clock = RhsClock(cost)
        pipelines.pin_dop853(TARGET_RTOL, solver=clock.solve_ivp)
        parts["peer"].append(clock.split())
    out: dict[str, float] = {}
    for side, values in parts.items():
        own, rhs, calls = (float(np.median([v[k] for v in values])) for k in range(3))
        out[f"scipy_own_{side}_s"], out[f"rhs_{side}_s"], out[f"rhs_calls_{side}"] = own, rhs, calls
    own = (out["scipy_own_ours_s"] + out["scipy_own_peer_s"]) / 2
    out["floor"] = (own + out["rhs_ours_s"]) / (own + out["rhs_peer_s"])
    out["ratio_if_rhs_free"] = own / (own + out["rhs_peer_s"])
    return out


def match(run, ladder, error, target: float) -> tuple[object, float, tuple[float, float]]:
    """(setting, end error, (steps, rhs calls)): the first setting of ``ladder`` whose end
    error is <= SLACK x target, else the last that ran (its error then shows the miss);
    RuntimeError if none ran."""
    last = None
    for setting in ladder:
        try:
            final, _, counts = run(setting)
        except RuntimeError:
            continue
        last = (setting, error(final), counts)
        if last[1] <= SLACK * target:
            break
    if last is None:
        raise RuntimeError(f"no setting of {ladder} integrated to the end")
    return last


def measure(name: str, repeat: int, rng: np.random.Generator) -> tuple[list[dict], list[dict]]:
    bench = case(name)
    pipelines = Pipelines(bench)
    rhs = pipelines.equations.forms["ode"].rhs
    reference = solve_ivp(
        lambda t, y: rhs(t, y)[0], (0.0, bench.t_end), bench.y0, method="DOP853",
        rtol=1e-13, atol=1e-13,
    ).y[:, -1]  # fmt: skip

    def error(final: np.ndarray) -> float:
        return float(np.abs(final - reference).max())

    final, _, counts = pipelines.pin_dop853(TARGET_RTOL)
    target = error(final)
    # label: (side, run, setting, end error, (steps, rhs calls))
    chosen: dict[str, tuple[str, Callable, object, float, tuple[float, float]]] = {
        "scipy DOP853 + pin.aba": ("peer", pipelines.pin_dop853, TARGET_RTOL, target, counts),
    }
    ours_dop853 = pipelines.ours("scipy-dop853", None)
    final, _, counts = ours_dop853(TARGET_RTOL)
    chosen["recursive jit + scipy-dop853 (same rtol)"] = (
        "ours", ours_dop853, TARGET_RTOL, error(final), counts,
    )  # fmt: skip
    candidates = {
        f"recursive jit + {k}" + (" (adams, functional)" if o else ""): (
            "ours",
            pipelines.ours(k, o),
            LADDER,
        )
        for k, o in OURS.items()
    }
    candidates |= {
        "CVODE Adams + pin.aba": ("peer", pipelines.pin_cvode("Adams"), LADDER),
        "CVODE BDF + pin.aba": ("peer", pipelines.pin_cvode("BDF"), LADDER),
        "MuJoCo RK4 (C, rollout)": ("peer", pipelines.mujoco_rk4, MUJOCO_STEPS),
        "scipy DOP853 + pin.aba (matched)": ("peer", pipelines.pin_dop853, LADDER),
    }
    if pipelines.anchor is not None:
        candidates[ANCHOR] = ("anchor", pipelines.anchor.run, LADDER)
        candidates[ANCHOR_C] = ("anchor", pipelines.anchor.run_c, LADDER)
    for label, (side, run, ladder) in candidates.items():
        chosen[label] = (side, run, *match(run, ladder, error, target))
    walls: dict[str, list[float]] = {label: [] for label in chosen}
    labels = list(chosen)
    for _ in range(repeat):
        for label in rng.permutation(labels):
            _, run, setting, _, _ = chosen[label]
            start = time.perf_counter()
            _, excluded, _ = run(setting)
            walls[label].append(time.perf_counter() - start - excluded)
    rows = [
        {
            "case": name, "side": side, "pipeline": label, "setting": setting, "end_error": err,
            "target_error": target, "wall_s": float(np.median(walls[label])),
            "wall_min_s": float(np.min(walls[label])), "steps": steps, "rhs_calls": calls,
            "us_per_rhs": 1e6 * float(np.median(walls[label])) / calls,
        }
        for label, (side, _, setting, err, (steps, calls)) in chosen.items()
    ]  # fmt: skip
    table = pd.DataFrame(rows)
    matched = table[(table.end_error <= SLACK * target) & ~table.pipeline.str.contains("same rtol")]
    best = {
        side: matched[matched.side == side].sort_values("wall_s").iloc[0].pipeline
        for side in ("ours", "peer", "anchor")
        if (matched.side == side).any()
    }
    pairs = {
        "a": ("recursive jit + scipy-dop853 (same rtol)", "scipy DOP853 + pin.aba"),
        "b": (best["ours"], best["peer"]),
        "c": (best["ours"], best.get("anchor", ANCHOR)),  # the faster anchor
    }
    for anchor in ANCHORS:
        if anchor in chosen and chosen[anchor][3] > SLACK * target:
            raise AssertionError(
                f"{name}: {anchor}: its end state is {chosen[anchor][3]:.2e} from the "
                f"reference at its tightest setting (allowed {SLACK * target:.2e})"
            )
    split = rhs_split(pipelines, ours_dop853, SPLIT_ROUNDS)
    targets = []
    load = os.getloadavg()[0]
    nan = NAN
    counted = {row["pipeline"]: row for row in rows}
    for pair, (ours, peer) in pairs.items():
        if peer in walls:
            ratios = np.array(walls[ours]) / np.array(walls[peer])
            median, low, high = interval(ratios)
            best_ratio, note = min(walls[ours]) / min(walls[peer]), ""
        else:  # the anchor could not be built: no number, the reason instead
            median = low = high = best_ratio = nan
            note = pipelines.anchor_note
        targets.append({
            "case": name, "pair": pair, "ours": ours, "peer": peer, "ratio": median,
            "low": low, "high": high, "best_ratio": best_ratio, "target": TARGETS[pair],
            "met": high <= TARGETS[pair], "note": note,
            "repeats": repeat, "load_1min": load, "cpu_count": os.cpu_count(),
            "cpu": cpu_model(), "date": time.strftime("%Y-%m-%d", time.gmtime()),
            "compile_s": pipelines.compile_s, "max_rel_diff": pipelines.max_rel_diff,
            # where the time goes: each side's rhs calls and median wall a call (all in it)
            "rhs_calls_ours_side": counted[ours]["rhs_calls"],
            "rhs_calls_peer_side": counted[peer]["rhs_calls"] if peer in counted else nan,
            "us_per_rhs_ours_side": counted[ours]["us_per_rhs"],
            "us_per_rhs_peer_side": counted[peer]["us_per_rhs"] if peer in counted else nan,
        })  # fmt: skip
        # the split is of pair (a) only: not measured for (b), so NaN there
        targets[-1] |= {k: (v if pair == "a" else float("nan")) for k, v in split.items()}
    return rows, targets


def verdict(row: pd.Series) -> str:
    """'met' when the whole interval is under the target, 'missed' (by how much) otherwise."""
    if pd.isna(row.ratio):
        return row.note or "not measured"
    if row.high <= row.target:
        return "met"
    if row.ratio <= row.target:
        return f"met at the median, not over its interval (up to {row.high:.2f})"
    return f"missed by {row.ratio / row.target:.2f}x"


def main(argv: list[str] | None = None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.simulation", description=__doc__)
    parser.add_argument("--repeat", type=int, default=21)
    parser.add_argument("--cases", nargs="+", choices=CASES, default=list(CASES))
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    rng = np.random.default_rng(0)
    rows, targets = [], []
    for name in args.cases:
        case_rows, case_targets = measure(name, args.repeat, rng)
        rows += case_rows
        targets += case_targets
        print(f"{name}: done", flush=True)
    table, summary = pd.DataFrame(rows), pd.DataFrame(targets)
    summary["verdict"] = summary.apply(verdict, axis=1)
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "simulation.csv", index=False)
    summary.to_csv(RESULTS / "simulation_targets.csv", index=False)
    with pd.option_context("display.width", 200, "display.max_colwidth", 60):
        print(table.to_string(index=False, float_format=lambda x: f"{x:.3g}"))
        print()
        shown = ["case", "pair", "ours", "peer", "ratio", "low", "high", "best_ratio", "floor"]
        shown += ["ratio_if_rhs_free", "target", "verdict"]
        print(summary[shown].to_string(index=False, float_format=lambda x: f"{x:.2f}"))
        print("\nwhere the time goes (each side: rhs calls, median wall a call in us, all in it):")
        shown = ["case", "pair", "rhs_calls_ours_side", "rhs_calls_peer_side"]
        shown += ["us_per_rhs_ours_side", "us_per_rhs_peer_side"]
        print(summary[shown].to_string(index=False, float_format=lambda x: f"{x:.2f}"))
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    return summary


if __name__ == "__main__":
    main()
