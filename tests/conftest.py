"""Fixtures shared by the test modules."""

from __future__ import annotations

import importlib
import sys

import pytest

from workbench.plugin.registry import REGISTRY


@pytest.fixture(autouse=True)
def _registry_left_as_found():
    """Every test leaves the plugin registry as it found it: a class given to
    ``workbench.run`` is registered, and a later test in the same process would list it
    (the catalog's check that every registered problem has its expected values)."""
    REGISTRY.discover()
    saved = {kind: dict(entries) for kind, entries in REGISTRY.entries.items()}
    yield
    for kind, entries in saved.items():
        REGISTRY.entries[kind] = entries


@pytest.fixture
def fake_plugins():
    """Register tests/fake_plugins.py for one test (the registry is restored after every
    test: ``_registry_left_as_found``)."""
    sys.modules.pop("tests.fake_plugins", None)
    yield importlib.import_module("tests.fake_plugins")
    sys.modules.pop("tests.fake_plugins", None)
