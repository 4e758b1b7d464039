"""The report's first screen: the decision table (cheapest trusted pair a problem and
target, margin or tie), its "why", the partial-sweep notice and the mechanism's picture."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.test_report import synthetic_results
from workbench.outputs.report import cheapest_pairs, prepare_results, write_report
from workbench.outputs.report.decision import decision_rows, decision_targets
from workbench.outputs.report.ranking import decide
from workbench.outputs.report.traits import model_traits, stiffness
from workbench.plugin.registry import get_problem
from workbench.runs import store


def costed(rows: list[tuple[str, float, float, float, float]]) -> pd.DataFrame:
    """Prepared rows of one problem: (pair 'f / i', scd, CPU median, CPU min, CPU max),
    each run timed three times."""
    records = []
    for k, (pair, scd, median, low, high) in enumerate(rows):
        formalism, integrator = pair.split(" / ")
        records.append(
            {"run_id": f"r{k}", "problem": "p", "formalism": formalism, "integrator": integrator,
             "rtol": 1e-6, "status": "ok", "scd": scd, "integrate_s": median,
             "integrate_cpu_s": median, "integrate_cpu_s_min": low, "integrate_cpu_s_max": high,
             "repeats": 3, "n_rhs": 100 + k}  # fmt: skip
        )
    return prepare_results(pd.DataFrame(records))


def test_overlapping_intervals_are_a_tie_and_apart_ones_a_margin() -> None:
    runs = costed([
        ("a / x", 6.0, 1.00, 0.95, 1.10),
        ("b / y", 6.5, 1.05, 0.98, 1.20),  # reaches into a's interval: tied
        ("c / z", 7.0, 3.00, 2.90, 3.20),
    ])  # fmt: skip
    tied = decide(runs, 4.0, "integrate_cpu_s")
    assert tied.pair == "a / x" and tied.is_tie and tied.tied == ["a / x", "b / y"]
    assert tied.verdict() == "tie"
    apart = decide(runs[runs["pair"] != "b / y"], 4.0, "integrate_cpu_s")
    assert not apart.is_tie and apart.runner_up == "c / z"
    assert apart.margin == pytest.approx(3.0) and apart.verdict() == "3.00x ahead"
    # a target only c reaches: the only pair
    assert decide(runs, 6.8, "integrate_cpu_s").verdict() == "only pair"
    assert decide(runs, 9.0, "integrate_cpu_s").verdict() == "none reached"


def test_the_runner_up_beside_a_tie_is_never_one_of_the_tied_pairs(tmp_path: Path) -> None:
    """The runner-up was the next cheapest pair: tied itself (its margin printed beside
    'tie'), or apart while a dearer pair with a wider interval was tied (qa3c F9, the
    four-bar at scd 2). It is the cheapest pair not tied, in every output."""
    runs = costed([
        ("a / x", 6.0, 1.00, 0.95, 1.05),
        ("b / y", 6.0, 1.02, 0.97, 1.08),  # the next cheapest, tied
        ("c / z", 6.0, 1.30, 1.25, 1.35),  # apart: the runner-up
    ])  # fmt: skip
    decision = decide(runs, 4.0, "integrate_cpu_s")
    assert decision.tied == ["a / x", "b / y"] and decision.runner_up == "c / z"
    assert decision.margin == pytest.approx(1.30)
    runs = costed([
        ("a / x", 6.0, 1.00, 0.95, 1.05),
        ("b / y", 6.0, 1.08, 1.06, 1.10),  # apart, narrow
        ("c / z", 6.0, 1.16, 0.96, 1.30),  # dearer, wide: tied
    ])  # fmt: skip
    decision = decide(runs, 4.0, "integrate_cpu_s")
    assert decision.tied == ["a / x", "c / z"] and decision.runner_up == "b / y"
    everyone = decide(runs[runs["pair"] != "b / y"], 4.0, "integrate_cpu_s")
    assert everyone.is_tie and everyone.runner_up == "" and np.isnan(everyone.margin)
    # the summary's CSV, Markdown, LaTeX (the paper's table) and page say it alike
    runs = costed([("a / x", 6.0, 1.00, 0.95, 1.05), ("b / y", 6.0, 1.02, 0.97, 1.08),
                   ("c / z", 6.0, 1.30, 1.25, 1.35)])  # fmt: skip
    write_report(runs, None, tmp_path, "cmd", progress=False)
    summary = pd.read_csv(tmp_path / "tables" / "summary.csv")
    reached = summary[summary["verdict"] == "tie"]
    assert len(reached) and (reached["runner-up"] == "c / z").all()
    assert (reached["tied pairs"] == "a / x, b / y").all()
    latex = (tmp_path / "tables" / "summary.tex").read_text(encoding="utf-8")
    assert "& c / z \\\\" in latex  # the paper names the runner-up, as the CSV does
    assert "runner-up: the cheapest pair not tied" in latex
    markdown = (tmp_path / "tables" / "summary.md").read_text(encoding="utf-8")
    assert "runner-up (cheapest pair not tied)" in markdown
    page = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert "runner-up (cheapest pair not tied)" in page


def test_a_cost_keeps_three_digits_so_a_column_has_one_format() -> None:
    """The decision table printed '39 ms' beside '39.1 ms' (qa3c F13), and 0.9996 s as
    '1e+03 ms'."""
    from workbench.outputs.report.decision import cost_text

    costs = [0.03896, 0.0391, 0.0232, 0.9996, 2.5e-5, 0.123]
    assert [cost_text(c, "integrate_cpu_s") for c in costs] == [
        "39.0 ms", "39.1 ms", "23.2 ms", "1.00 s", "25.0 \N{MICRO SIGN}s", "123 ms",
    ]  # fmt: skip
    assert cost_text(1234.0, "n_rhs") == "1,234 rhs"


def test_without_intervals_a_tie_is_not_claimed_and_the_reader_is_told() -> None:
    runs = costed([("a / x", 6.0, 1.0, 0.9, 1.1), ("b / y", 6.0, 1.05, 0.9, 1.2)])
    runs["repeats"] = 1  # one sample each: no spread
    decision = decide(runs, 4.0, "integrate_cpu_s")
    assert not decision.is_tie and not decision.tie_known
    assert "tie unknown" in decision.verdict()
    # rows of an older schema: no CPU interval, the wall-time one scaled to CPU time
    runs = costed([("a / x", 6.0, 1.0, np.nan, np.nan), ("b / y", 6.0, 1.05, np.nan, np.nan)])
    runs["integrate_s"] = [2.0, 2.1]
    runs["integrate_s_min"], runs["integrate_s_max"] = [1.9, 2.05], [2.2, 2.3]
    decision = decide(runs, 4.0, "integrate_cpu_s")
    assert decision.tie_known and decision.is_tie
    assert decision.high == pytest.approx(1.1)  # 2.2 s wall x (1 / 2) CPU per wall


def test_the_cheapest_pair_table_and_the_decision_agree() -> None:
    runs = prepare_results(synthetic_results())
    runs["repeats"] = 3
    runs["wall_s_min"], runs["wall_s_max"] = runs["wall_s"] * 0.98, runs["wall_s"] * 1.02
    table = cheapest_pairs(runs, targets=(2.0, 4.0), cost="wall_s")
    for row in table.itertuples():
        decision = decide(runs[runs["problem"] == row.problem], row._2, "wall_s")
        assert row.pair == (decision.pair or "none reached")
        assert row.verdict == decision.verdict()
    assert {"runner-up", "margin", "verdict", "tied pairs"} <= set(table.columns)


def test_targets_are_those_the_sweep_reaches() -> None:
    runs = costed([("a / x", 6.5, 1.0, 0.9, 1.1)])
    assert decision_targets(runs, "integrate_cpu_s") == [2.0, 4.0, 6.0]
    runs = costed([("a / x", 11.0, 1.0, 0.9, 1.1)])
    assert decision_targets(runs, "integrate_cpu_s") == [4.0, 8.0, 10.0]


def test_stiffness_is_read_from_the_integrators_statistics() -> None:
    def rows(explicit_steps: int) -> pd.DataFrame:
        return pd.DataFrame(
            {"status": ["ok"] * 4, "rtol": [1e-4, 1e-6] * 2,
             "n_jac": [0, 0, 12, 20], "n_steps": [explicit_steps] * 2 + [40, 60],
             "n_rejected": [1, 2, 0, 0]}  # fmt: skip
        )

    assert stiffness(rows(2000)).startswith("stiff: explicit integrators took 42x")  # 50x, 33x
    assert stiffness(rows(60)).startswith("not stiff: explicit integrators took 1.2x")
    assert stiffness(rows(60)[2:]) == ""  # implicit ones only: the runs cannot tell


def test_a_driven_joint_is_a_trait_of_its_problem() -> None:
    """The rotating ring's spin is prescribed: its equations depend on time, which the
    "why" said nothing of (it read "spatial, 2 bodies, 2 joints")."""
    family, traits = model_traits(get_problem("rotating-ring")().model())
    assert family == "open trees and chains"
    assert "rheonomic (1 driven joint: spin; equations that depend on time)" in traits
    assert not any("rheonomic" in t for t in model_traits(get_problem("slider-crank")().model())[1])


def test_the_page_opens_with_the_decision_table_grouped_by_family(tmp_path: Path) -> None:
    results = synthetic_results(problems=("simple-pendulum", "four-bar", "heavy-top"))
    results.loc[results["problem"] == "four-bar", "scd"] -= 2.0  # never reaches scd 6
    index = write_report(results, None, tmp_path, "cmd")
    page = index.read_text(encoding="utf-8")
    assert page.index('id="decision"') < page.index('id="overview"')
    families = re.findall(r'<tr class="family"><th colspan="\d+">([^<]+)</th>', page)
    assert families == ["open trees and chains", "rotations (spherical and free joints)",
                        "closed loops"]  # fmt: skip
    assert "closed loops (1 cut joint" in page and "Why:" in page
    assert page.count('class="none">not reached') == 1  # the four-bar at scd >= 6
    decision = pd.read_csv(tmp_path / "tables" / "decision.csv")
    assert list(decision.columns[:2]) == ["family", "problem"]
    assert len(decision) == 3
    # every problem shows its picture in its row and its section
    for problem in ("simple-pendulum", "four-bar", "heavy-top"):
        assert (tmp_path / "figures" / f"{problem}-picture.png").is_file()
        assert page.count(f'src="figures/{problem}-picture.png"') == 2


def test_a_partial_sweep_says_so_on_the_first_screen(tmp_path: Path) -> None:
    results = synthetic_results(problems=("simple-pendulum",))
    directory = tmp_path / "sweep"
    (directory / store.RUNS_DIR).mkdir(parents=True)
    done = results.iloc[:8]
    for row in done.to_dict("records"):
        (directory / store.RUNS_DIR / f"{row['run_id']}.json").write_text(
            json.dumps({k: v for k, v in row.items() if v == v}), encoding="utf-8"
        )
    store.write_plan(directory, results["run_id"], "suite first-look")
    from workbench.outputs.report import report_directory

    page = report_directory(directory, progress=False).read_text(encoding="utf-8")
    notice = re.search(r'<p class="notice" id="coverage">(.*?)</p>', page, re.S)
    assert notice is not None and page.index('id="coverage"') < page.index('id="decision"')
    assert "planned 12 runs and 8 of them have a row here, 4 missing" in notice.group(1)
    assert "suite first-look" in notice.group(1)
    store.write_plan(directory, done["run_id"], "suite first-look")  # the whole plan: quiet
    page = report_directory(directory, progress=False).read_text(encoding="utf-8")
    assert 'id="coverage"' not in page


def test_run_sweep_records_its_plan(tmp_path: Path) -> None:
    from workbench.runs.sweep import parse_spec

    spec = parse_spec(
        'problems = ["simple-pendulum"]\nformalisms = ["minimal-ode"]\n'
        'integrators = ["scipy-dop853"]\ntolerances = [1e-4, 1e-6]\n',
        "test",
    )
    from workbench.runs.sweep import run_sweep

    run_sweep(spec, jobs=1, out=tmp_path, show_progress=False, say=lambda line: None)
    plan = store.load_plan(tmp_path)
    assert plan is not None and plan["runs"] == 2 == len(plan["run_ids"])
    assert set(plan["run_ids"]) == {run.run_id for run in spec.runs}


def test_picture_places_the_shapes_at_the_initial_pose() -> None:
    """Every body is placed, with a proper rotation, in the plane of a planar model."""
    from workbench.outputs.report.picture import body_poses
    from workbench.outputs.report.traits import problem_model

    model = problem_model("four-bar")
    poses = body_poses(model)
    assert set(poses) == set(model.bodies)
    for position, rotation in poses.values():
        assert np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-12)
        assert position[2] == pytest.approx(0.0)  # planar: in the x-y plane
    rows = decision_rows(prepare_results(synthetic_results(problems=("four-bar",))), [4.0],
                         "wall_s")  # fmt: skip
    assert rows[0].family == "closed loops"


def test_steps_an_integrator_did_not_report_are_not_counted() -> None:
    """-1 means 'not reported' (the store's convention): never a -1 % rejection rate."""
    runs = pd.DataFrame(
        {"status": ["ok"] * 4, "rtol": [1e-4, 1e-6] * 2, "n_jac": [0, 0, 12, 20],
         "n_steps": [100, 200, 40, 60], "n_rejected": [-1, -1, 0, 0]}  # fmt: skip
    )
    said = stiffness(runs)
    assert "-1" not in said and "rejected" not in said
    assert said.startswith("not stiff: explicit integrators took 2.9x")  # 2.5x and 3.3x


def test_fixed_step_runs_do_not_make_a_pendulum_stiff() -> None:
    """The simple pendulum is not stiff: DOP853 takes fewer steps than CVODE BDF at the
    same rtol. RK4's steps are the step rtol asks (1 ms: 10,000 steps, none rejected), not
    the problem's doing; counted as an explicit method's, they made the report say
    "stiff: explicit integrators took 14x the steps of implicit ones, rejected 0%"."""
    from workbench.execution.execute import RunSpec, execute_run

    rows = []
    for integrator in ("scipy-dop853", "sundials-cvode-bdf", "rk4"):
        spec = RunSpec("simple-pendulum", "minimal-ode", integrator, 1e-6, 1e-9, {}, {"index": 1})
        row = execute_run(spec).row
        assert row["status"] == "ok", row["message"]
        rows.append(row)
    dop853, bdf, rk4 = rows
    assert dop853["n_steps"] < bdf["n_steps"] < rk4["n_steps"]
    assert np.isfinite(rk4["fixed_step_s"]) and rk4["n_rejected"] == 0
    said = stiffness(prepare_results(pd.DataFrame(rows)))
    ratio = dop853["n_steps"] / bdf["n_steps"]
    assert said.startswith(f"not stiff: explicit integrators took {ratio:.2g}x"), said
    assert "rejected" not in said  # DOP853 does not report its rejections; rk4 has none


def test_a_tie_is_explained_in_the_cost_measure_that_made_it() -> None:
    """Counted right-hand sides have no spread: two pairs tie when the counts are equal,
    and the why says so, not that timed samples overlap (they played no part)."""
    from workbench.outputs.report.decision import why
    from workbench.outputs.report.traits import problem_traits

    runs = costed([("a / x", 6.0, 1.0, 0.9, 1.1), ("b / y", 6.0, 3.0, 2.9, 3.1)])
    runs["n_rhs"] = [500, 500]  # the same count, very different times
    by_count = decide(runs, 4.0, "n_rhs")
    assert by_count.is_tie and not decide(runs, 4.0, "integrate_cpu_s").is_tie
    traits = problem_traits(runs)
    text = why(traits, [by_count], runs, "n_rhs")
    assert "right-hand-side counts are equal" in text and "timed samples" not in text
    timed = costed([("a / x", 6.0, 1.00, 0.95, 1.10), ("b / y", 6.5, 1.05, 0.98, 1.20)])
    text = why(traits, [decide(timed, 4.0, "integrate_cpu_s")], timed, "integrate_cpu_s")
    assert "timed samples' ranges overlap" in text


def test_every_cost_measure_has_its_label_as_a_table_header() -> None:
    """A report in any measure heads its cost column with the measure's name and unit
    (``--cost work`` showed ``work_s``)."""
    from workbench.outputs.report.cost import COST_MEASURES
    from workbench.outputs.report.tables import header

    for column, label in COST_MEASURES.values():
        assert header(column) == label.removesuffix(" [-]")  # a count has no unit


def test_the_ranking_table_says_when_it_lists_only_the_first_pairs(tmp_path: Path) -> None:
    """Nine pairs, eight printed in the LaTeX: its caption says so (a pair left out of the
    table was not said), the CSV keeps all nine, and the cost-at-target caption claims no
    'within reach' of the pairs it prints."""
    from workbench.outputs.report.writer import RANKED_SHOWN, overview_of

    results = synthetic_results(
        formalisms=("minimal-ode", "absolute-dae", "recursive"),
        integrators=("radau", "generalized-alpha", "scipy-dop853"),
    )
    (tmp_path / "figures").mkdir(), (tmp_path / "tables").mkdir()
    overview_of(prepare_results(results), tmp_path)
    ranking = pd.read_csv(tmp_path / "tables" / "ranking.csv")
    assert len(ranking) == 9 > RANKED_SHOWN
    # the mean is over the problems a pair reached, not all (qa3c F13): the header says so
    assert "geometric mean of cost / best over the problems reached" in ranking.columns
    caption = (tmp_path / "tables" / "ranking.tex").read_text()
    assert f"the first {RANKED_SHOWN} of 9 pairs" in caption
    assert "within reach of the best on the most" not in (
        tmp_path / "tables" / "cost-at-target.tex"
    ).read_text()


def test_a_margin_is_printed_with_the_digits_that_tell_it_from_one() -> None:
    """'.3g' printed a 1.003 margin as '1x ahead' and the heat map's 1.017 as '1', the
    winner's own value; and 1.4 beside 1.19."""
    from workbench.outputs.report.tables import ratio_text

    assert [ratio_text(v) for v in (1.0, 1.003, 1.017, 1.4, 1.19, 7.3, 12.34, 140.2)] == [
        "1", "1.003", "1.017", "1.40", "1.19", "7.30", "12.3", "140",
    ]  # fmt: skip
    runs = costed([("a / x", 6.0, 1.000, 0.999, 1.001), ("b / y", 6.0, 1.003, 1.002, 1.004)])
    assert decide(runs, 4.0, "integrate_cpu_s").verdict() == "1.003x ahead"


def test_a_cost_ratio_prints_one_way_wherever_a_reader_sees_it(tmp_path: Path) -> None:
    """The summary printed a margin to 4 significant digits ('2.103') where the decision
    table said '2.10x': every table a reader sees (Markdown, LaTeX, the page, ``workbench
    results``) prints a cost ratio as the verdicts do; the CSV keeps every digit."""
    from workbench.outputs.report.tables import times_text
    from workbench.outputs.results_table import results_table

    results = synthetic_results()
    write_report(results, None, tmp_path, "cmd", progress=False)
    tables = tmp_path / "tables"
    summary = pd.read_csv(tables / "summary.csv")
    margins = summary["margin"].dropna()
    assert len(margins) and (margins.round(3) != margins).all()  # the CSV: every digit
    markdown = (tables / "summary.md").read_text()
    latex = (tables / "summary.tex").read_text()
    page = (tmp_path / "index.html").read_text()
    for margin in margins:
        shown = times_text(margin)  # '1.70x', as the verdict's '1.70x ahead'
        assert re.fullmatch(r"\d+(\.\d+)?x", shown)
        assert f"| {shown} |" in markdown and f"& {shown} " in latex
        assert f"<td>{shown}</td>" in page
        assert f"{margin:.4g} " not in markdown.replace("|", " ")  # the old '2.103'
    for name in ("cost-at-target", "ranking"):  # the heat map's and the ranking's ratios
        text = (tables / f"{name}.md").read_text().split("\nTable:")[0]
        assert re.search(r"\| \d+(\.\d+)?x \|", text), name
        assert not re.search(r"\| \d\.\d{4} \|", text), name
    printed = results_table(results)
    verdicts = printed["verdict"][printed["verdict"].str.contains("x ahead")]
    assert len(verdicts) and all(re.search(r" \d+(\.\d+)?x ahead", v) for v in verdicts)


def test_pairs_cut_short_by_the_tolerance_grid_are_named_in_the_why() -> None:
    """A pair still improving at the tightest rtol it ran, short of the target the table
    awards: its cost there was not measured, so the "why" says the grid decided (a stiff
    mechanism's implicit pairs at scd 4.4-5.2 at rtol 1e-7 beside an explicit winner)."""
    runs = costed([
        ("a / x", 4.0, 1.0, 0.9, 1.1), ("a / x", 6.5, 2.0, 1.9, 2.1),  # reaches 6
        ("b / y", 3.0, 0.5, 0.4, 0.6), ("b / y", 5.2, 0.8, 0.7, 0.9),  # still improving
        ("c / z", 5.0, 0.5, 0.4, 0.6), ("c / z", 4.9, 0.9, 0.8, 1.0),  # saturated
    ])  # fmt: skip
    runs["rtol"] = [1e-4, 1e-7] * 3
    (row,) = decision_rows(runs, [4.0, 6.0], "integrate_cpu_s")
    assert "Not measured: 1 pair(s) still improving at their tightest rtol (1e-07) fell " \
        "short of scd 6; a tighter rtol would price them there (b / y)" in row.why
    reaching = runs[runs["pair"] != "b / y"]
    assert "Not measured" not in decision_rows(reaching, [4.0, 6.0], "integrate_cpu_s")[0].why
    # b / y's tighter rtol was run and failed (or was warned): it was measured, not cut
    # short by the grid ("a tighter rtol would price them" was wrong advice)
    tried = pd.concat([runs, runs[runs["pair"] == "b / y"].tail(1).assign(
        rtol=1e-10, status="failed", scd=float("nan"), run_id="tried")])  # fmt: skip
    assert "Not measured" not in decision_rows(tried, [4.0, 6.0], "integrate_cpu_s")[0].why


def test_a_close_margin_on_a_run_not_timed_again_says_so(tmp_path: Path) -> None:
    """The quick suite named iftomm-a05's winner at scd 6 '1.093x ahead' on two runs too
    long for the repeat budget, so never timed again at moments apart, while the page said
    the close calls were: back-to-back samples share the machine's moment. The verdict
    says 'not timed again', in every output; a wide margin, or runs timed again, do not."""
    runs = costed([("a / x", 6.0, 0.62, 0.613, 0.621), ("b / y", 6.0, 0.678, 0.669, 0.70)])
    runs["retimed"] = [0, 0]
    decision = decide(runs, 4.0, "integrate_cpu_s")
    assert decision.runner_up == "b / y" and not decision.timed_apart
    assert decision.verdict() == "1.094x ahead (not timed again: may not hold)"
    # the runner-up named before the caveat, which is not the runner-up's
    from workbench.outputs.report.decision import cell_summary

    assert cell_summary(decision, "integrate_cpu_s") == (
        "a / x, 620 ms, 1.094x ahead of b / y (not timed again: may not hold)"
    )
    table = cheapest_pairs(runs, targets=(4.0,), cost="integrate_cpu_s")
    assert table.loc[0, "verdict"] == decision.verdict()
    runs["retimed"] = [5, 0]  # the runner-up's samples still back to back
    assert not decide(runs, 4.0, "integrate_cpu_s").timed_apart
    runs["retimed"] = [5, 5]
    assert decide(runs, 4.0, "integrate_cpu_s").verdict() == "1.094x ahead"
    far = costed([("a / x", 6.0, 0.62, 0.613, 0.621), ("b / y", 6.0, 2.0, 1.9, 2.1)])
    assert decide(far.assign(retimed=0), 4.0, "integrate_cpu_s").verdict() == "3.23x ahead"
    # a count is no timing: its margin needs no second sweep
    assert decide(runs.assign(retimed=0), 4.0, "n_rhs").timed_apart
    # the paper's tables say what the words mean, in their captions
    write_report(runs.assign(retimed=0), None, tmp_path, "cmd", progress=False)
    for name in ("decision", "summary"):
        latex = (tmp_path / "tables" / f"{name}.tex").read_text(encoding="utf-8")
        caption = latex.split(r"\caption{", 1)[1].split(r"\label", 1)[0]
        assert "(not timed again: may not hold)" in latex
        assert "may not survive a second sweep" in " ".join(caption.split())
    # the LaTeX summary prints no error column: its caption says where the errors are
    summary = (tmp_path / "tables" / "summary.tex").read_text(encoding="utf-8")
    assert "errors (in the CSV and Markdown) are pose errors" in " ".join(summary.split())
