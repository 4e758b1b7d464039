"""The result of ``workbench.run``: its row, trajectory, series and plots."""

from __future__ import annotations

import html
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from workbench.errors import ConfigError, WorkbenchError
from workbench.execution.row_schema import SERIES_COLUMNS, STATE_PREFIX

# the row's columns a result shows first (its HTML and its repr)
HEADLINE = [
    ("status", "status"),
    ("form", "form integrated"),
    ("scd", "scd (correct digits at the end)"),
    ("err_end", "pose error at the end (m)"),
    ("drift_pos_max", "max position drift"),
    ("drift_vel_max", "max velocity drift"),
    ("energy_err_max", "max energy error / energy in motion"),
    ("integrate_s", "integration wall time (s)"),
    ("integrate_cpu_s", "integration CPU time (s)"),
    ("n_rhs", "right-hand sides"),
    ("n_steps", "steps"),
]


@dataclass
class Result:
    """One run: ``row`` (a pandas Series, the columns of
    ``workbench.execution.row_schema.SCHEMA``), ``series`` (drift, energy and error at every output
    sample) and ``trajectory`` (time ``t`` in s and every named coordinate, velocity and
    multiplier). ``equations`` and ``problem`` are the objects the run used (None if it
    stopped before building them)."""

    row: pd.Series
    series: pd.DataFrame
    equations: Any = None
    problem: Any = None
    charts: list[Any] | None = None

    @property
    def run_id(self) -> str:
        """The run's id: a hash of its problem, formalism, integrator, options and tolerances."""
        return str(self.row["run_id"])

    @property
    def ok(self) -> bool:
        """True if the run finished and its audit found nothing wrong."""
        return self.row["status"] == "ok" and not self.row.get("warnings")

    @property
    def trajectory(self) -> pd.DataFrame:
        """States at the output samples reached: ``t`` and one column per state, named as
        the equations name them (q, v, then ``lambda:<constraint>`` where the form has
        multipliers)."""
        names = [c for c in self.series.columns if c.startswith(STATE_PREFIX)]
        frame = self.series[["t", *names]]
        return frame.rename(columns=lambda c: c.removeprefix(STATE_PREFIX))

    @property
    def drift(self) -> pd.DataFrame:
        """Constraint residuals over time: ``t``, ``drift_pos``, ``drift_vel``, ``drift_nh``."""
        return self.series[["t", "drift_pos", "drift_vel", "drift_nh"]]

    @property
    def energy(self) -> pd.DataFrame:
        """Energy error over time: ``t``, ``energy_err`` (NaN if not conservative), |E - E0|
        / S (:data:`~workbench.execution.row_schema.ENERGY_ERROR`)."""
        return self.series[["t", "energy_err"]]

    @property
    def error(self) -> pd.DataFrame:
        """Pose error against the reference over time: ``t``, ``ref_err`` (m)."""
        return self.series[["t", "ref_err"]]

    def poses(self) -> pd.DataFrame:
        """Every body's pose at the output samples: ``t``, then per body ``<body>.x``,
        ``.y``, ``.z`` (m) and the unit quaternion ``.p0`` .. ``.p3`` (scalar first)."""
        if self.equations is None:
            raise WorkbenchError(
                f"run {self.run_id} has no equations to compute poses from "
                f"({self.row['status']}: {self.row['message']})"
            )
        trajectory = self.trajectory
        times = trajectory["t"].to_numpy()
        q = trajectory.iloc[:, 1 : 1 + self.equations.nq].to_numpy()
        poses = np.empty((len(times), len(self.equations.observables.body_names), 7))
        atlas = getattr(self.equations, "atlas", None)
        charts = self.charts if self.charts and atlas is not None else [None] * len(times)
        for chart in dict.fromkeys(charts):  # each sample in its own chart's coordinates
            rows = np.array([k for k, c in enumerate(charts) if c == chart], dtype=int)
            equations = self.equations if chart is None else atlas.equations(chart)
            poses[rows] = equations.observables.poses_along(times[rows], q[rows])
        columns = {"t": times}
        for b, body in enumerate(self.equations.observables.body_names):
            for k, part in enumerate(("x", "y", "z", "p0", "p1", "p2", "p3")):
                columns[f"{body}.{part}"] = poses[:, b, k]
        return pd.DataFrame(columns)

    # ---- plots (matplotlib) ------------------------------------------------------------

    def plot(self, columns: list[str] | None = None, ax: Any = None) -> Any:
        """The trajectory's coordinates (or the named ``columns``: a name or a list of
        names of ``trajectory``) against time; the Axes."""
        trajectory = self.trajectory
        names = [columns] if isinstance(columns, str) else columns
        names = names or trajectory.columns[1 : 1 + _nq(self, trajectory)].tolist()
        unknown = [name for name in names if name not in trajectory.columns[1:]]
        if unknown:
            raise ConfigError(
                f"run {self.run_id}: no trajectory column {', '.join(map(repr, unknown))}; "
                f"its columns: {', '.join(trajectory.columns[1:])}"
            )
        ax = _axes(ax)
        for name in names:
            ax.plot(trajectory["t"], trajectory[name], label=name)
        ax.set_xlabel("t [s]")
        velocities = [name.endswith(".v") for name in names]
        shown = "velocities" if all(velocities) else "coordinates" if not any(velocities) else (
            "coordinates and velocities")  # fmt: skip
        ax.set_ylabel(f"{shown} (SI units)")
        ax.set_title(_plot_title(self.row))
        if len(names) <= 12:
            ax.legend(fontsize="small")
        return ax

    def plot_drift(self, ax: Any = None) -> Any:
        """Position, velocity and nonholonomic constraint residuals against time (log y)."""
        return _plot_series(self, ["drift_pos", "drift_vel", "drift_nh"], "constraint residual", ax)

    def plot_energy(self, ax: Any = None) -> Any:
        """The energy error |E - E0| / S against time (log y; S as in ``energy``)."""
        return _plot_series(self, ["energy_err"], "energy error / energy in motion", ax)

    def plot_error(self, ax: Any = None) -> Any:
        """The pose error against the reference over time (log y)."""
        return _plot_series(self, ["ref_err"], "pose error [m]", ax)

    # ---- display -------------------------------------------------------------------------

    def headline(self) -> dict[str, Any]:
        """The row's main columns by their labels (status, scd, errors, drift, cost)."""
        return {label: self.row.get(column) for column, label in HEADLINE if column in self.row}

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={_text(v)}" for k, v in self.headline().items() if _text(v))
        message = self.row.get("message")  # why a run failed or was skipped
        shown += f", message={message}" if message else ""
        return f"<Result {self.run_id} {_title(self.row)}: {shown}>"

    def _repr_html_(self) -> str:
        rows = "".join(
            f"<tr><th style='text-align:left'>{html.escape(label)}</th>"
            f"<td style='text-align:left'>{html.escape(_text(value))}</td></tr>"
            for label, value in self.headline().items()
        )
        notes = "".join(
            f"<p><b>{name}</b>: {html.escape(str(self.row[name]))}</p>"
            for name in ("message", "warnings")
            if self.row.get(name)
        )
        states = self.series.shape[0], len(self.trajectory.columns) - 1
        return (
            f"<h4>{html.escape(_title(self.row))}</h4><table>{rows}</table>{notes}"
            f"<p><small>run {self.run_id}: trajectory of {states[0]} samples x {states[1]} "
            "states (<code>.trajectory</code>), series <code>.drift</code>, "
            "<code>.energy</code>, <code>.error</code>; <code>.row</code> has every column"
            "</small></p>"
        )


def _title(row: pd.Series) -> str:
    return f"{row['problem']} / {row['formalism']} / {row['integrator']} @ rtol {row['rtol']:g}"


def _plot_title(row: pd.Series) -> str:
    """The run on two lines: two plots side by side in a default figure keep their titles
    apart (on one line each overran its neighbour)."""
    return f"{row['problem']}, rtol {row['rtol']:g}\n{row['formalism']} / {row['integrator']}"


def _text(value: Any) -> str:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.4g}"
    return "" if value is None else str(value)


def _nq(result: Result, trajectory: pd.DataFrame) -> int:
    if result.equations is not None:
        return result.equations.nq
    return sum(1 for c in trajectory.columns[1:] if not c.endswith(".v") and ":" not in c)


def _axes(ax: Any) -> Any:
    if ax is None:
        import matplotlib.pyplot as plt

        # constrained layout: the x label and title stay inside the figure when saved
        _, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
    return ax


def _plot_series(result: Result, columns: list[str], label: str, ax: Any) -> Any:
    """``columns`` of the series on a log y axis: only their positive finite values (a 0
    or NaN is left out, not clamped, so the axis spans what was measured); a column with
    none is not drawn and a note on the axes says why."""
    ax = _axes(ax)
    series = result.series
    missing = []
    for column in columns:
        values = series[column].to_numpy(dtype=float)
        shown = np.isfinite(values) & (values > 0)
        if shown.any():
            ax.plot(series["t"], np.where(shown, values, np.nan), label=column)
        else:
            missing.append(f"{column}: {_why_not_shown(values)}")
    ax.set_yscale("log")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(label)
    ax.set_title(_plot_title(result.row))
    handles, labels = ax.get_legend_handles_labels()
    if handles:  # a column not drawn gets a legend line that says why, without a handle
        from matplotlib.lines import Line2D

        blank = Line2D([], [], linestyle="none")
        ax.legend(handles + [blank] * len(missing), labels + missing, fontsize="small")
    elif missing:  # nothing drawn: no invented y scale, the note in the middle instead
        times = series["t"].to_numpy(dtype=float)
        if len(times) > 1:
            ax.set_xlim(times.min(), times.max())
        ax.tick_params(axis="y", which="both", left=False, labelleft=False)
        note = "nothing to plot on a log axis:\n" + "\n".join(missing)
        ax.text(0.5, 0.5, note, transform=ax.transAxes, ha="center", va="center")
    return ax


def _why_not_shown(values: np.ndarray) -> str:
    """What a series with no positive finite value holds, in a few words."""
    measured = values[~np.isnan(values)]
    if not measured.size:
        return "not measured (NaN)"
    if not measured.any():
        return "exactly 0" + (" where measured" if measured.size < values.size else "")
    return "has no positive finite value"


__all__ = ["Result", "SERIES_COLUMNS"]
