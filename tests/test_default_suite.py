"""The full sweep (workbench/runs/suites/full.toml) names only integrators that run:
each is installed and registered (none left out silently by ``missing_plugins = "skip"``),
and each is given a form it accepts by every formalism of the sweep at the sweep's options,
so no pairing of the default sweep is skipped for a form or index mismatch."""

from __future__ import annotations

import tomllib

from workbench.plugin.registry import REGISTRY, get_formalism, get_integrator
from workbench.runs.sweep_spec import FULL_SUITE, load_spec, suite_text


def named_integrators() -> list[str]:
    return [
        entry if isinstance(entry, str) else entry["name"]
        for entry in tomllib.loads(suite_text(FULL_SUITE))["integrators"]
    ]


def test_every_integrator_of_the_default_sweep_is_registered_and_runs() -> None:
    registered = {i.name for i in REGISTRY.list("integrator") if i.plugin is not None}
    named = named_integrators()
    assert set(named) <= registered, sorted(set(named) - registered)
    assert {run.integrator for run in load_spec(FULL_SUITE).runs} == set(named)


def test_every_pairing_of_the_default_sweep_offers_an_accepted_form() -> None:
    mismatches = set()
    for run in load_spec(FULL_SUITE).runs:
        formalism = get_formalism(run.formalism)
        forms = formalism.forms(formalism.parse_options(run.formalism_options))
        if get_integrator(run.integrator).select_form(forms) is None:
            mismatches.add((run.formalism, run.integrator, str(forms)))
    assert not mismatches
