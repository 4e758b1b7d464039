"""The conformance kit and a formalism that enforces its constraints approximately (issue
34.3): a penalty formalism (tests/penalty_formalism.py) passes when it declares the
residual it keeps, fails when its constraints are worse than declared, and, declaring
nothing, fails as it always did (exact constraints are then what is asked)."""

from __future__ import annotations

import importlib
import sys

import pytest

from workbench.plugin.registry import REGISTRY
from workbench.testing import check_formalism

LOOP = ["slider-crank"]  # a closed loop: the penalty acts
STIFFNESS = 1e6  # per unit mass: the residual settles near 1e-3 (9e-4 measured)


@pytest.fixture
def penalty():
    REGISTRY.discover()
    saved = {kind: dict(entries) for kind, entries in REGISTRY.entries.items()}
    sys.modules.pop("tests.penalty_formalism", None)
    yield importlib.import_module("tests.penalty_formalism").PenaltyLoops
    for kind, entries in saved.items():
        REGISTRY.entries[kind] = entries
    sys.modules.pop("tests.penalty_formalism", None)


def results(report) -> dict[str, object]:
    return {(r.check, r.problem): r for r in report.results}


def test_a_penalty_formalism_passes_when_it_declares_its_tolerance(penalty):
    report = check_formalism(penalty, LOOP, options={"stiffness": STIFFNESS, "declared": 1e-3})
    assert report.ok, report
    found = results(report)
    assert "constraints held to 0.001" in found["approximation", ""].message
    assert "approximate constraints" in found["dof", "slider-crank"].message
    assert found["accelerations", "slider-crank"].status == "skip"
    constraints = found["constraints", "slider-crank"]
    assert 1e-4 < constraints.error <= 1e-3  # a real penalty residual, within the promise


def test_it_fails_when_its_constraints_are_worse_than_declared(penalty):
    report = check_formalism(penalty, LOOP, options={"stiffness": STIFFNESS, "declared": 1e-5})
    failed = {r.check for r in report.failures}
    assert "constraints" in failed
    assert failed <= {"constraints", "energy", "trajectory"}, report
    # a stiffer penalty keeps the same promise: the residual falls as 1/stiffness
    stiffer = check_formalism(penalty, LOOP, options={"stiffness": 1e8, "declared": 1e-4})
    assert stiffer.ok, stiffer


def test_declaring_nothing_asks_for_exact_constraints(penalty):
    report = check_formalism(penalty, LOOP, options={"stiffness": STIFFNESS})
    failed = {r.check for r in report.failures}
    assert {"dof", "accelerations", "constraints"} <= failed
    assert "approximation" not in {r.check for r in report.results}


@pytest.mark.parametrize("declared", [-1e-3, float("inf")])
def test_a_declaration_must_be_a_residual(penalty, declared):
    report = check_formalism(penalty, LOOP, options={"declared": declared}, checks="structural")
    (failure,) = report.failures
    assert failure.check == "approximation" and "must be None" in failure.message
