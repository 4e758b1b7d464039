"""The user guide's example integrator passes the conformance kit (it failed five checks:
no docstring, a fixed 1 ms step that ignored rtol, no step count)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

from workbench.plugin.registry import REGISTRY, PluginInfo
from workbench.testing import check_integrator

GUIDE = Path(__file__).resolve().parents[1] / "docs" / "user-guide.md"


def test_the_user_guides_integrator_passes_the_kit(tmp_path, monkeypatch) -> None:
    blocks = re.findall(r"```python\n(.*?)```", GUIDE.read_text(encoding="utf-8"), re.S)
    (source,) = [b for b in blocks if "class ExplicitEuler(Integrator)" in b]
    (tmp_path / "guide_euler.py").write_text(source, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    REGISTRY.discover()
    monkeypatch.setattr(REGISTRY, "entries", {k: dict(v) for k, v in REGISTRY.entries.items()})
    module = __import__("guide_euler")
    try:
        plugin = module.ExplicitEuler
        info = PluginInfo("integrator", plugin.name, plugin, plugin.__module__)
        REGISTRY.entries["integrator"][plugin.name] = info
        check_integrator(plugin).raise_if_failed()
    finally:
        sys.modules.pop("guide_euler", None)
