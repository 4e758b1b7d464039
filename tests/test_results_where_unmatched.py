"""``workbench results --where`` that keeps no row says so, and names the values a
``column=value`` condition could have had: a misspelled problem name printed an empty
table (or, by problem, nothing at all) and exit 0, with no hint why."""

from __future__ import annotations

from typer.testing import CliRunner

from workbench.cli import app

runner = CliRunner()


def test_a_where_that_keeps_no_row_names_the_values_of_its_column(tmp_path) -> None:
    out = tmp_path / "out"
    made = runner.invoke(
        app,
        ["run", "simple-pendulum", "-f", "minimal-ode", "-i", "rk4", "-o", "step=0.01",
         "--out", str(out)],
    )  # fmt: skip
    assert made.exit_code == 0, made.output
    for by in ("problem", "pair", "run"):
        result = runner.invoke(
            app, ["results", str(out), "--by", by, "-w", "problem=simple-pendlum"]
        )
        assert result.exit_code == 0, result.output  # a query that matches nothing is no error
        assert "Traceback" not in result.output
        assert (
            f"note: no run of the 1 in {out} meets --where problem=simple-pendlum; "
            "no run has problem=simple-pendlum (its values: simple-pendulum)"
        ) in result.output, result.output
    kept = runner.invoke(app, ["results", str(out), "-w", "problem=simple-pendulum"])
    assert kept.exit_code == 0 and "note:" not in kept.output, kept.output
    none_failed = runner.invoke(app, ["results", str(out), "--by", "run", "-w", "status=failed"])
    assert "no run has status=failed (its values: ok)" in none_failed.output


def test_a_problem_swept_over_options_is_kept_whole_by_its_name(tmp_path) -> None:
    """A problem run with two option sets is named with them, pendulum[initial_angle=..]:
    -w problem=NAME keeps none of its rows, and the note says which condition does."""
    out = tmp_path / "out"
    for angle in ("0.3", "0.6"):
        made = runner.invoke(
            app,
            ["run", "simple-pendulum", "-f", "minimal-ode", "-i", "rk4", "-o", "step=0.01",
             "-o", f"initial_angle={angle}", "--out", str(out)],
        )  # fmt: skip
        assert made.exit_code == 0, made.output
    result = runner.invoke(app, ["results", str(out), "-w", "problem=simple-pendulum"])
    assert result.exit_code == 0 and "Traceback" not in result.output, result.output
    assert "problem_name=simple-pendulum keeps them all" in " ".join(result.output.split())
    kept = runner.invoke(app, ["results", str(out), "--by", "run",
                               "-w", "problem_name=simple-pendulum", "-f", "csv"])  # fmt: skip
    assert kept.exit_code == 0 and "note:" not in kept.output, kept.output
    assert len(kept.output.strip().splitlines()) == 3  # the header and both runs
