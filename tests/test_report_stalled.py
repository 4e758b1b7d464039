"""A pair whose runs each look fine but whose error does not shrink with the tolerance is
named at the top of the report: a formalism written wrong (here the scaffold's template
left as it is, unit mass matrix and no forces) conserves its energy and its constraints,
so its rows were ``ok`` at scd -0.3 beside 9.6 and nothing said so. Correct pairs of real
runs are not named (their scd grows with 1/rtol)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pandas as pd

import workbench as wb
from tests.test_report import synthetic_results
from tests.test_scaffold import isolated_registry  # noqa: F401 - a fixture
from workbench.outputs.report import write_report
from workbench.outputs.report.analysis import prepare_results, stalled_pairs
from workbench.plugin.scaffold import scaffold

TOLERANCES = (1e-4, 1e-6, 1e-8)


def template_formalism(
    folder: Path, name: str = "stalled-template", forces: str = "ca.SX.zeros(k.nv)"
) -> type:
    """``workbench new formalism NAME``'s module with its TODO raise deleted: M = I and the
    forces ``forces`` (an expression in the template's ``k``; as written, Q = 0)."""
    scaffold("formalism", name, where=folder)
    module = name.replace("-", "_")
    path = folder / f"{module}.py"
    text = path.read_text(encoding="utf-8")
    start = text.index("        # TODO: write the mass matrix and the forces")
    text = text[:start] + text[text.index("        mass = ca.SX.eye"):]
    path.write_text(text.replace("ca.SX.zeros(k.nv)", forces), "utf-8")
    spec = importlib.util.spec_from_file_location(module, path)
    loaded = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(loaded)
    return getattr(loaded, "".join(part.title() for part in name.split("-")))


def test_a_pair_that_does_not_converge_is_named_and_correct_ones_are_not(
    tmp_path: Path, isolated_registry: None  # noqa: F811 - the fixture
) -> None:
    wrong = template_formalism(tmp_path)
    # the two-joint robot starts moving: the template's free motion (M = I, Q = 0) runs,
    # each run fine alone, and never approaches the reference
    rows = [
        wb.run("two-joint-robot", formalism, "scipy-dop853", rtol=rtol).row
        for formalism in ("minimal-ode", wrong)
        for rtol in TOLERANCES
    ]
    runs = prepare_results(pd.DataFrame(rows))
    assert (runs["status"] == "ok").all() and not runs["warnings"].any()  # each looks fine
    found = stalled_pairs(runs)
    assert len(found) == 1 and found[0].startswith("two-joint-robot: stalled-template /")
    assert "workbench.testing formalism stalled-template checks them" in found[0]
    assert stalled_pairs(runs[runs["formalism"] == "minimal-ode"]) == []
    page = write_report(runs, None, tmp_path / "report", "cmd", progress=False).read_text("utf-8")
    assert 'id="stalled"' in page and "stalled-template / scipy-dop853 stays at scd" in page
    # on the pendulum released at rest the template moves nothing: each row says so itself
    at_rest = wb.run("simple-pendulum", wrong, "scipy-dop853", rtol=1e-6).row
    assert at_rest["status"] == "ok" and "nothing moved" in at_rest["warnings"]


def test_pairs_that_converge_or_have_one_fixed_step_are_not_named() -> None:
    runs = prepare_results(synthetic_results())  # scd grows as rtol shrinks
    assert stalled_pairs(runs) == []
    flat = runs.copy()
    behind = flat["pair"] == flat["pair"].iloc[0]
    flat.loc[behind, "scd"] = 0.5  # stuck, far behind the others
    assert len(stalled_pairs(flat)) == 2  # on each of the two problems
    warned = flat.copy()
    warned.loc[behind, "warnings"] = "left its assembly branch at a singular configuration"
    assert stalled_pairs(warned) == []  # said in its rows already
    flat.loc[behind, "fixed_step_s"] = 1e-3  # the tolerance sets no step here
    assert stalled_pairs(flat) == []
    flat["fixed_step_s"] = float("nan")
    flat["penetration_max"] = 0.0  # contacts: a step or a stiffness sets the error
    assert stalled_pairs(flat) == []
