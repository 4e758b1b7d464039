"""An output folder that is a file (``--out results.csv``, a spec's ``out``, ``report
--out``) is one line naming the file before any work, not an OS error (``File exists``,
``Not a directory``) after the run or the report's seconds of work."""

from __future__ import annotations

from typer.testing import CliRunner

from workbench.cli import app

runner = CliRunner()


def one_error_line(text: str) -> str:
    lines = [line for line in text.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in text, text
    return lines[0]


def test_run_sweep_and_report_name_an_output_folder_that_is_a_file(tmp_path) -> None:
    taken = tmp_path / "results.csv"
    taken.write_text("a file, not a folder\n")
    run = ["run", "simple-pendulum", "-f", "minimal-ode", "-i", "rk4", "-o", "step=0.01"]
    spec = tmp_path / "spec.toml"
    spec.write_text(
        f'out = "{taken}"\nproblems = ["simple-pendulum"]\nformalisms = ["minimal-ode"]\n'
        'integrators = ["rk4"]\ntolerances = [1e-6]\n'
    )
    results = tmp_path / "results"
    made = runner.invoke(app, [*run, "--out", str(results)])
    assert made.exit_code == 0, made.output
    for args, target in (
        ([*run, "--out", str(taken)], taken),
        ([*run, "--out", str(taken / "sub")], taken / "sub"),
        (["sweep", str(spec)], taken),
        (["report", str(results), "--out", str(taken)], taken),
        (["paper", str(results), "--out", str(taken)], taken / "report"),
    ):
        result = runner.invoke(app, args)
        assert result.exit_code == 2, (args, result.output)
        line = one_error_line(result.output)
        assert f"cannot write into {target}: {taken} is a file, not a folder" in line, line
    assert taken.read_text() == "a file, not a folder\n"
    assert not (results / "report").exists()  # nothing was written before the refusal
