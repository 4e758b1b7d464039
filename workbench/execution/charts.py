"""Integrate chart by chart: coordinate re-partitioning (Wehage and Haug) in the run.

A formalism whose coordinates hold only near part of the motion (minimal velocities of a
velocity partition, singular where the block W_d solved for the dependent velocities loses
rank) offers an :class:`~workbench.equations.Atlas`. The run then integrates in segments:
after each segment it reads the current chart's conditioning at the output samples, and
at the first sample where it has fallen below SWITCH_RATIO times the best chart's there,
it drops the rest of the segment and restarts the integrator from the last good sample on
the best chart (the state carried over through the full velocities). Integrators only
solve segments; their statistics add up over every segment, including the dropped tails
(work really paid).

The first segment runs to the end, so a run that never needs another chart is the very
run it was without the atlas (restarts alone move the last digit or two: measured, up to
0.8 of scd with CVODE Adams). After a switch a segment spans 1.5 times the samples the
previous chart lasted (at least MIN_HORIZON), doubling while its chart holds, so a chart
that degrades as soon as the last wastes little; the first segment's tail after its
switch is the main waste (knife edge, 10 rad: about 2.3 times the right-hand sides of one
partition with CVODE Adams and with DOP853 at rtol 1e-12).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from workbench.equations.initial import accelerations
from workbench.plugin.integrator import SolverStats, Trajectory

SWITCH_RATIO = 0.3  # leave a chart whose conditioning is below this times the best's
MIN_HORIZON = 8  # output samples in a segment, at least


@dataclass
class ChartedTrajectory(Trajectory):
    """A trajectory whose samples are in several charts: ``charts[k]`` is sample k's;
    ``switches``: (t, chart) where a new chart began."""

    charts: list[Any] = field(default_factory=list)
    switches: list[tuple[float, Any]] = field(default_factory=list)


def integrate_on_charts(integrator: Any, equations: Any, y0: np.ndarray, yp0: np.ndarray,
                        times: np.ndarray, rtol: float, atol: float, options: Any,
                        form: str) -> ChartedTrajectory:  # fmt: skip
    """``integrator.solve`` segment by segment on ``equations.atlas`` (module doc)."""
    atlas = equations.atlas
    chart, start, chart_began = atlas.home, 0, 0
    horizon = len(times)
    nq, nv = equations.nq, equations.nv
    kept_t: list[np.ndarray] = []
    kept_y: list[np.ndarray] = []
    charts: list[Any] = []
    switches: list[tuple[float, Any]] = []
    segments: list[SolverStats] = []
    just_switched = False
    while True:
        stop = min(len(times), start + horizon)
        segment = integrator.solve(
            atlas.equations(chart), y0, yp0, times[start:stop], rtol, atol, options, form
        )
        segments.append(segment.stats)
        seg_t, seg_y = np.asarray(segment.times), np.atleast_2d(segment.y)
        if seg_t.size == 0:  # failed before its first sample
            return _joined(form, kept_t, kept_y, charts, switches, segments, segment)
        first = 1 if charts else 0  # a restart's first sample is the last one kept
        bad = _first_degraded(atlas, chart, seg_t, seg_y[:, :nq])
        if bad == 1 and just_switched:  # no ping-pong: keep one sample at least
            bad = 2 if len(seg_t) > 2 else None
        end = len(seg_t) if bad is None else bad
        kept_t.append(seg_t[first:end])
        kept_y.append(seg_y[first:end])
        charts += [chart] * max(0, end - first)
        last = end - 1
        t_last, y_next = float(seg_t[last]), seg_y[last, : nq + nv]
        if bad is None:
            if not segment.success or stop >= len(times):
                return _joined(form, kept_t, kept_y, charts, switches, segments, segment)
            horizon *= 2
        else:
            target = atlas.best(t_last, y_next[:nq])
            if target == chart:  # the last good sample still prefers it: the bad one does not
                target = atlas.best(float(seg_t[bad]), seg_y[bad, :nq])
            horizon = max((3 * (start + last - chart_began)) // 2, MIN_HORIZON)
            y_next = atlas.transfer(chart, target, t_last, y_next)
            chart, chart_began = target, start + last
            switches.append((t_last, chart))
        just_switched = bad is not None
        start += last
        y0, yp0 = _restart(atlas.equations(chart), form, t_last, y_next)


def _first_degraded(atlas: Any, chart: Any, times: np.ndarray, q: np.ndarray) -> int | None:
    """The first sample (after the segment's first) where ``chart`` has fallen below
    SWITCH_RATIO times the best chart's conditioning, or None."""
    for k in range(1, len(times)):
        t = float(times[k])
        best = atlas.best(t, q[k])
        if best != chart and atlas.conditioning(chart, t, q[k]) < SWITCH_RATIO * (
            atlas.conditioning(best, t, q[k])
        ):
            return k
    return None


def _restart(equations: Any, form: str, t: float,
             state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(y0, yp0) of a segment starting at t from the state (q, v) in ``equations``' chart;
    derivatives (and multipliers) from the chart's own equations."""
    nq = equations.nq
    y0 = np.asarray(state, dtype=float)
    acceleration, multipliers, qdot = accelerations(equations, t, y0[:nq], y0[nq:])
    yp0 = np.concatenate([np.ravel(qdot), np.ravel(acceleration)])
    n = equations.forms["dae"].n if form == "dae" else y0.size
    extra = np.zeros(n - y0.size)
    extra[: min(multipliers.size, extra.size)] = np.ravel(multipliers)[: extra.size]
    return np.concatenate([y0, extra]), np.concatenate([yp0, np.zeros(n - y0.size)])


def _joined(form: str, kept_t: list[np.ndarray], kept_y: list[np.ndarray], charts: list[Any],
            switches: list[tuple[float, Any]], segments: list[SolverStats],
            last: Trajectory) -> ChartedTrajectory:  # fmt: skip
    """One trajectory from the kept parts; statistics summed over every segment."""
    stats = SolverStats(fixed_step=segments[0].fixed_step)
    for name in ("n_rhs", "n_jac", "n_steps", "n_rejected", "n_lu", "n_newton"):
        values = [getattr(s, name) for s in segments]
        setattr(stats, name, -1 if any(v < 0 for v in values) else int(sum(values)))
    for name in ("setup_s", "integrate_s", "cpu_s"):
        setattr(stats, name, float(sum(getattr(s, name) for s in segments)))
    times = np.concatenate(kept_t) if kept_t else np.zeros(0)
    if not kept_y:
        return ChartedTrajectory(form, times, np.atleast_2d(last.y), last.success, last.message,
                                 last.t_reached, stats, list(last.warnings),
                                 charts=charts, switches=switches)  # fmt: skip
    t_reached = last.t_reached if not last.success else float(times[-1]) if times.size else math.nan
    return ChartedTrajectory(
        form, times, np.concatenate(kept_y), last.success, last.message, t_reached, stats,
        list(last.warnings), charts=charts, switches=switches,
    )  # fmt: skip


def switch_note(atlas: Any, trajectory: Any) -> str:
    """A row's note on the charts a run used ("" when it kept its first)."""
    switches = getattr(trajectory, "switches", [])
    if not switches:
        return ""
    shown = ", ".join(f"t = {t:.4g} s to {atlas.name(chart)}" for t, chart in switches[:6])
    more = f" and {len(switches) - 6} more" if len(switches) > 6 else ""
    return (
        f"{len(switches)} chart switches (re-partitioned where the chart degraded): "
        f"{shown}{more}"
    )
