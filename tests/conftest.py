"""Fixtures shared by the test modules."""

from __future__ import annotations

import importlib
import sys

import pytest

from workbench.plugin.registry import REGISTRY


@pytest.fixture
def fake_plugins():
    """Register tests/fake_plugins.py for one test, then restore the registry."""
    REGISTRY.discover()
    saved = {kind: dict(entries) for kind, entries in REGISTRY.entries.items()}
    sys.modules.pop("tests.fake_plugins", None)
    yield importlib.import_module("tests.fake_plugins")
    for kind, entries in saved.items():
        REGISTRY.entries[kind] = entries
    sys.modules.pop("tests.fake_plugins", None)
