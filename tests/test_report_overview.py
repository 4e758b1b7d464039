"""The report's overview: Pareto fronts, cost at a fixed accuracy, the recommendation,
and the axes of its figures (labelled, with units, numbers even on short log axes)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.test_report import synthetic_results, synthetic_series
from workbench.outputs.report import prepare_results, write_report
from workbench.outputs.report.figures import measured_quantities, work_precision_figure
from workbench.outputs.report.overview import (
    cost_at_target,
    cost_ratio,
    overview_target,
    pareto_mask,
    recommend,
)


def rows(
    points: list[tuple[str, str, float, float]], warnings: tuple[int, ...] = ()
) -> pd.DataFrame:
    """Runs (problem, pair 'f / i', scd, wall_s), all ok; the rows in ``warnings`` warned."""
    frame = pd.DataFrame(
        [
            {
                "run_id": f"r{k}",
                "problem": problem,
                "formalism": pair.split(" / ")[0],
                "integrator": pair.split(" / ")[1],
                "rtol": 1e-6,
                "status": "ok",
                "scd": scd,
                "wall_s": wall,
                "n_rhs": 100.0,
                "warnings": "singular passage: lost rank" if k in warnings else "",
            }
            for k, (problem, pair, scd, wall) in enumerate(points)
        ]
    )
    return prepare_results(frame)


def test_pareto_front_keeps_exactly_the_undominated_runs() -> None:
    runs = rows(
        [
            ("p", "a / x", 4.0, 1.0),  # front: cheapest
            ("p", "a / x", 6.0, 2.0),  # front
            ("p", "b / y", 5.0, 3.0),  # dominated by (6, 2)
            ("p", "b / y", 8.0, 5.0),  # front: most accurate
            ("p", "c / z", 6.0, 2.0),  # ties (6, 2): neither dominates the other
            ("p", "c / z", 9.0, 0.5),  # would dominate all, but carries a warning
        ],
        warnings=(5,),
    )
    assert list(pareto_mask(runs)) == [True, True, False, True, True, False]


def test_pareto_front_equals_the_pairwise_definition_on_random_points_with_ties() -> None:
    rng = np.random.default_rng(7)
    for size in (1, 2, 5, 40, 300):
        # few distinct values: many equal costs, equal digits and equal points
        points = [("p", "a / x", float(rng.integers(0, 6)), float(rng.integers(1, 6)))
                  for _ in range(size)]  # fmt: skip
        runs = rows(points)
        costs, digits = runs["wall_s"].to_numpy(), runs["scd"].to_numpy()
        expected = [
            not np.any((costs <= c) & (digits >= d) & ((costs < c) | (digits > d)))
            for c, d in zip(costs, digits, strict=True)
        ]
        assert list(pareto_mask(runs)) == expected, size


def test_recommendation_counts_problems_within_the_factor_and_ignores_warned_runs() -> None:
    points = []
    for problem, a_wall, b_wall in (("p1", 1.0, 1.5), ("p2", 1.0, 3.0), ("p3", 4.0, 1.0)):
        points += [(problem, "a / x", 7.0, a_wall), (problem, "b / y", 7.0, b_wall)]
    points.append(("p2", "b / y", 7.0, 0.1))  # b's cheap run on p2 is not to be trusted
    runs = rows(points, warnings=(len(points) - 1,))
    costs = cost_at_target(runs, 6.0)
    assert costs.loc["p2", "b / y"] == 3.0  # the warned 0.1 s run does not count
    ratio = cost_ratio(costs)
    assert np.allclose(ratio.min(axis=1), 1.0)
    found = recommend(runs, target=6.0)
    # a: within 2x on p1 (1), p2 (1); not p3 (4x). b: p1 (1.5), p3 (1); not p2 (3x).
    # Both 2 of 3; a's geometric mean ratio (4^(1/3) = 1.59) beats b's (4.5^(1/3) = 1.65).
    assert found.pair == "a / x" and found.within == 2 and found.reached == 3
    assert found.sentence.startswith("a / x is within 2x of the best wall time on 2 of 3")
    assert "scd >= 6" in found.sentence
    # b scores the same: the sentence says so and what decided (it named a alone)
    assert (
        "; so is b / y: a / x is named for the lower geometric mean of its cost ratios "
        "to the best (1.59x against 1.65x)." in found.sentence
    )


def test_pairs_scoring_the_same_are_named_with_whether_the_ranking_ties_their_costs() -> None:
    """Two pairs within 2x on both problems: the sentence named the first by its geometric
    mean although the table of cheapest pairs called their costs tied (qa3c F10); it says
    on how many problems their timed ranges overlap, and when on all, that the order is
    not a measured difference."""
    points = [(p, pair, 7.0, wall) for p in ("p1", "p2")
              for pair, wall in (("a / x", 1.0), ("b / y", 1.2))]  # fmt: skip
    runs = rows(points)
    runs["wall_s_min"], runs["wall_s_max"] = runs["wall_s"] * 0.95, runs["wall_s"] * 1.05
    apart = recommend(runs, target=6.0)  # [0.95, 1.05] against [1.14, 1.26] on both
    assert apart.pair == "a / x" and apart.costs_tied == (0, 2)
    assert "so is b / y: a / x is named for the lower geometric mean" in apart.sentence
    assert "their costs tie" not in apart.sentence
    runs.loc[runs["problem"] == "p1", "wall_s_max"] *= 1.1  # p1: a's range reaches 1.155
    once = recommend(runs, target=6.0)
    assert once.costs_tied == (1, 2)
    assert once.sentence.endswith(
        "; their costs tie at scd >= 6 on 1 of the 2 problems they both reached (as in "
        "the table of the cheapest pairs)."
    )
    runs["wall_s_max"] = runs["wall_s"] * 1.2  # overlapping on both problems
    tied = recommend(runs, target=6.0)
    assert tied.costs_tied == (2, 2)
    assert tied.sentence.endswith("on 2 of the 2 problems they both reached (as in the table "
                                  "of the cheapest pairs), so that order does not say which "
                                  "is cheaper.")  # fmt: skip
    # three pairs scoring the same: all named, in the plural
    three = rows(points + [(p, "c / z", 7.0, 1.3) for p in ("p1", "p2")])
    assert "; so are b / y, c / z: a / x is named" in recommend(three, target=6.0).sentence


def test_target_is_the_highest_reached_on_two_thirds_of_the_problems() -> None:
    runs = rows([("p1", "a / x", 8.5, 1.0), ("p2", "a / x", 6.5, 1.0), ("p3", "a / x", 5.0, 1.0)])
    assert overview_target(runs) == 6.0  # 8 on one of three, 6 on two of three
    nothing = recommend(rows([("p", "a / x", 1.0, 1.0)]), target=6.0)
    assert nothing.pair is None and "no recommendation" in nothing.sentence


def test_a_short_log_axis_still_has_numbers(tmp_path: Path) -> None:
    """Wall times 2-6 ms (less than a decade) and rhs counts 300-900: each log axis must
    show at least two numbers, and every axis a label with a unit."""
    runs = rows([("p", "a / x", 4.0, 2e-3), ("p", "a / x", 6.0, 6e-3)])
    runs["n_rhs"] = [300.0, 900.0]
    (tmp_path / "figures").mkdir()
    figure = work_precision_figure(runs, tmp_path, "p", "wall_s")
    assert figure is not None
    assert all(axis.label and "[" in axis.label and axis.numeric for axis in figure.axes)
    assert {axis.label for axis in figure.axes} >= {
        "wall time [s]",
        "right-hand-side evaluations [-]",
    }


def test_tick_labels_of_a_short_log_axis() -> None:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    from workbench.outputs.report.figures import log_axis

    figure, ax = plt.subplots()
    ax.plot([2e-3, 6e-3], [1, 2])
    log_axis(ax, "x")
    figure.canvas.draw()
    lo, hi = ax.get_xlim()
    shown = [
        t.get_text()
        for t in ax.xaxis.get_ticklabels() + ax.xaxis.get_ticklabels(minor=True)
        if t.get_text() and lo <= t.get_position()[0] <= hi
    ]
    plt.close(figure)
    assert len(shown) >= 2, shown


def test_not_measured_and_exactly_zero_are_told_apart() -> None:
    chosen = pd.DataFrame({"run_id": ["r"]})
    series = synthetic_series("r")
    series["drift_vel"] = np.nan  # no velocity constraint
    drawn, absent = measured_quantities(chosen, {"r": series})
    assert [column for column, _label in drawn] == ["drift_pos", "energy_err"]
    assert "not measured" in absent["drift_vel"]
    assert "exactly zero" in absent["drift_nh"]
    assert all("[" in label for _column, label in drawn)


def test_overview_opens_the_page(tmp_path: Path) -> None:
    index = write_report(synthetic_results(), synthetic_series, tmp_path, "cmd")
    page = index.read_text(encoding="utf-8")
    assert page.index('id="overview"') < page.index("Cheapest pair reaching each accuracy")
    assert "within 2x of the best wall time" in page
    assert (tmp_path / "tables" / "cost-at-target.tex").is_file()
    assert (tmp_path / "tables" / "pareto.csv").is_file()


def test_two_front_runs_a_hair_apart_in_scd_print_apart(tmp_path: Path) -> None:
    """A sweep's Pareto table showed scd '2.992' on two rows: two runs (recursive and
    minimal-ode under DOP853 integrate the same ODE), the dearer on the front by 3e-6
    digits. Not a duplicate: the table prints the digits that tell them apart."""
    from workbench.outputs.report.writer import overview_of

    runs = rows([("p", "recursive / dop853", 2.9923241519, 0.0133),
                 ("p", "minimal-ode / dop853", 2.9923271470, 0.0160),
                 ("p", "recursive / bdf", 1.3320510260, 0.0112),
                 ("p", "minimal-ode / bdf", 1.2, 0.02)])  # fmt: skip
    (tmp_path / "figures").mkdir(), (tmp_path / "tables").mkdir()
    overview_of(runs, tmp_path)
    front = pd.read_csv(tmp_path / "tables" / "pareto.csv")
    assert list(front["pair"]) == ["recursive / bdf", "recursive / dop853",
                                   "minimal-ode / dop853"]  # three runs, none twice
    assert front["scd"].iloc[1] == 2.9923241519  # the CSV: every digit
    markdown = (tmp_path / "tables" / "pareto.md").read_text(encoding="utf-8")
    printed = [line.split(" | ")[3] for line in markdown.splitlines()[2:] if line.startswith("| p")]
    assert len(set(printed)) == 3, printed  # '2.99232' and '2.99233', not '2.992' twice
    assert printed[0] == "1.33205"  # one format a column
    page = write_report(runs, None, tmp_path / "report", "cmd", progress=False)
    assert page.read_text(encoding="utf-8").count("<td>2.9923") == 2


def test_convergence_plot_of_fixed_step_runs_fits_the_order(tmp_path: Path) -> None:
    """Rows with a fixed step and an end error C h^2 (a second-order method): the figure
    is drawn and its legend states the order 2.00; adaptive rows (NaN step) are left out."""
    from workbench.outputs.report.overview_figures import (
        convergence_figure,
        fixed_step_rows,
        observed_order,
    )

    steps = np.array([1e-2, 1e-3, 1e-4])
    points = [("p", "a / alpha", 3.0, 1.0)] * 3 + [("p", "a / dop", 8.0, 1.0)]
    runs = rows(points)
    runs["fixed_step_s"] = [*steps, np.nan]
    runs["length_scale"] = 2.0
    runs["err_end"] = [*(2.0 * 0.3 * steps**2), 1e-9]
    chosen = fixed_step_rows(runs)
    assert list(chosen["pair"].unique()) == ["a / alpha"]
    assert observed_order(
        chosen["fixed_step_s"].to_numpy(), chosen["relative_error"].to_numpy()
    ) == (pytest.approx(2.0))
    (tmp_path / "figures").mkdir()
    figure = convergence_figure(runs, tmp_path)
    assert figure is not None and (tmp_path / "figures" / "overview-convergence.png").is_file()
    assert {axis.label for axis in figure.axes} == {"step h [s]", "end pose error / L [-]"}
    assert convergence_figure(runs[runs["pair"] == "a / dop"], tmp_path) is None


def test_seven_formalisms_get_seven_line_styles_and_markers() -> None:
    """Colour by integrator; line style and marker by formalism, all distinct for 7+."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    from workbench.outputs.report.figures import PairStyles

    pairs = [(f"f{k}", f"i{j}") for k in range(7) for j in range(3)]
    runs = rows([("p", f"{f} / {i}", 4.0, 1.0) for f, i in pairs])
    styles = PairStyles(runs)
    looks = {(str(s["linestyle"]), s["marker"], s["color"]) for s in map(styles, runs["pair"])}
    assert len(looks) == 21  # every pair looks different
    assert len({str(styles.marks[f][1]) for f in styles.formalisms}) == 7  # line styles
    assert len({styles.marks[f][0] for f in styles.formalisms}) == 7  # markers


def test_a_problems_counts_tell_ok_runs_with_warnings_apart() -> None:
    """A problem's line read "15 runs: 15 ok." while its status table counted one of
    them as "ok with warnings"."""
    import pandas as pd

    from workbench.outputs.report.analysis import status_counts

    runs = pd.DataFrame({"status": ["ok", "ok", "failed", "ok"],
                         "warnings": ["", "energy: drifts", "", None]})  # fmt: skip
    assert status_counts(runs) == "2 ok, 1 ok with warnings, 1 failed"
    assert status_counts(runs.assign(warnings="x")[:2]) == "2 ok with warnings"
