"""workbench.execution.charts: integration chart by chart, on a toy atlas of two charts.

q turns at a constant rate 1 (q' = v = 1). Chart "c" holds with conditioning |cos q|,
chart "s" with |sin q| (the two velocity partitions of a knife edge, heading q): each is
singular every pi, a quarter turn after the other is.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from workbench.execution.charts import SWITCH_RATIO, integrate_on_charts
from workbench.plugin.integrator import SolverStats, Trajectory


class TwoCharts:
    home = "c"

    def __init__(self) -> None:
        self.transfers: list[tuple[str, str, float]] = []
        self.built = {name: toy_equations(self) for name in ("c", "s")}

    def conditioning(self, chart: str, t: float, q: np.ndarray) -> float:
        return float(abs(np.cos(q[0]) if chart == "c" else np.sin(q[0])))

    def best(self, t: float, q: np.ndarray) -> str:
        return max(("c", "s"), key=lambda chart: self.conditioning(chart, t, q))

    def equations(self, chart: str):
        return self.built[chart]

    def transfer(self, source: str, target: str, t: float, y: np.ndarray) -> np.ndarray:
        self.transfers.append((source, target, t))
        return np.array(y, dtype=float)

    def name(self, chart: str) -> str:
        return chart


def toy_equations(atlas: TwoCharts):
    rhs = SimpleNamespace(rhs=lambda t, y: (np.array([y[1], 0.0]),))
    return SimpleNamespace(nq=1, nv=1, forms={"ode": rhs}, atlas=atlas)


class Exact:
    """Solves q' = v exactly; fails (after its first samples) where chart "c" is singular
    if ``fail_near_singular``, as an integrator may at a singular partition."""

    def __init__(self, fail_near_singular: bool = False) -> None:
        self.fail_near_singular = fail_near_singular
        self.calls: list[tuple[str, float, float]] = []

    def solve(self, equations, y0, yp0, times, rtol, atol, options, form):
        chart = next(name for name, e in equations.atlas.built.items() if e is equations)
        self.calls.append((chart, float(times[0]), float(times[-1])))
        q = y0[0] + y0[1] * (times - times[0])
        y = np.stack([q, np.full_like(q, y0[1])], axis=1)
        stats = SolverStats(n_rhs=10, n_steps=len(times))
        if self.fail_near_singular and chart == "c":
            near = np.flatnonzero(np.abs(np.cos(q)) < 0.05)
            if near.size:
                k = int(near[0])
                return Trajectory(form, times[:k], y[:k], False, "step too small",
                                  float(times[k - 1]), stats)  # fmt: skip
        return Trajectory(form, times, y, True, "", float(times[-1]), stats)


def run(integrator: Exact, t_end: float = 2 * np.pi):
    atlas = TwoCharts()
    times = np.linspace(0.0, t_end, 401)
    equations = atlas.equations("c")
    trajectory = integrate_on_charts(
        integrator, equations, np.array([0.0, 1.0]), np.array([1.0, 0.0]), times, 1e-8,
        1e-10, None, "ode",
    )  # fmt: skip
    return atlas, times, trajectory


def check_charts(atlas: TwoCharts, times: np.ndarray, trajectory) -> None:
    assert trajectory.success and np.array_equal(trajectory.times, times)  # each sample once
    assert np.allclose(trajectory.y[:, 0], times)  # the state carried through every restart
    for t, q, chart in zip(times, trajectory.y[:, :1], trajectory.charts, strict=True):
        best = atlas.conditioning(atlas.best(t, q), t, q)
        assert atlas.conditioning(chart, t, q) >= SWITCH_RATIO * best


def test_a_full_turn_switches_chart_before_each_singularity() -> None:
    """One turn: "c" degrades near pi/2 and 3 pi/2, "s" near pi and 2 pi (the end): four
    switches, each from the last sample the old chart held, none needed at the end."""
    integrator = Exact()
    atlas, times, trajectory = run(integrator)
    check_charts(atlas, times, trajectory)
    assert [chart for _, chart in trajectory.switches] == ["s", "c", "s", "c"]
    spacing, holds = times[1], np.arctan(SWITCH_RATIO)  # a chart holds to this from singular
    for (t, _), singular in zip(trajectory.switches, np.pi / 2 * np.arange(1, 5), strict=True):
        assert singular - holds - spacing < t <= singular - holds + 1e-12
    assert [(a, b) for a, b, _ in atlas.transfers] == [("c", "s"), ("s", "c")] * 2
    assert trajectory.stats.n_rhs == 10 * len(integrator.calls)
    assert trajectory.stats.n_steps == sum(
        int(np.sum((times >= a - 1e-12) & (times <= b + 1e-12))) for _, a, b in integrator.calls
    )


def test_a_segment_that_fails_at_a_singular_chart_goes_on_in_another() -> None:
    """The integrator gives up near the singularity of "c": the samples it reached show the
    chart degrading, so the run goes on from the last good one in "s" and finishes."""
    integrator = Exact(fail_near_singular=True)
    atlas, times, trajectory = run(integrator)
    check_charts(atlas, times, trajectory)
    assert len(trajectory.switches) == 4


def test_a_run_that_needs_no_other_chart_is_one_segment() -> None:
    integrator = Exact()
    atlas, times, trajectory = run(integrator, t_end=1.0)  # |cos q| > 0.54 > 0.3 |sin q|
    assert integrator.calls == [("c", 0.0, 1.0)] and trajectory.switches == []
    assert set(trajectory.charts) == {"c"} and atlas.transfers == []
