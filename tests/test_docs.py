"""The documentation: a short README, a site whose pages are all reachable, and no
reference to notes outside the repository. (`mkdocs build --strict` in .ci/run builds the
site and executes its notebooks.)"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]


def test_the_readme_is_short_and_keeps_the_ci_test_command() -> None:
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) < 200
    # .ci/run runs `python -m pytest -q`: the README's command is the same command
    assert '.venv/bin/pip install -e ".[test]" && .venv/bin/python -m pytest' in readme
    assert "python -m pytest -q" in (REPO / ".ci" / "run").read_text(encoding="utf-8")


def test_every_page_of_docs_is_in_the_site_navigation() -> None:
    config = yaml.load((REPO / "mkdocs.yml").read_text(encoding="utf-8"), Loader=yaml.BaseLoader)

    def pages(entries):
        for entry in entries:
            for value in entry.values():
                yield from pages(value) if isinstance(value, list) else [value]

    listed = set(pages(config["nav"]))
    docs = REPO / "docs"
    on_disk = {str(p.relative_to(docs)) for p in docs.rglob("*.md")}
    on_disk |= {str(p.relative_to(docs)) for p in (docs / "notebooks").glob("*.py")}
    assert on_disk == listed


def test_links_of_the_readme_lead_to_files() -> None:
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#]+)\)", readme)
    assert targets and all((REPO / t).exists() for t in targets if "://" not in t), targets


def test_nothing_refers_to_notes_outside_the_repository() -> None:
    outside = re.compile(r"DESIGN\.md|STYLE\.md|/work/|shared notes")
    found = []
    for folder in ("workbench", "plugins", "problems", "docs", "benchmarks", "tests"):
        for path in (REPO / folder).rglob("*"):
            if path.suffix in (".py", ".md", ".toml", ".j2", ".yml") and path != Path(__file__):
                text = path.read_text(encoding="utf-8", errors="replace")
                found += [f"{path.relative_to(REPO)}: {m}" for m in outside.findall(text)]
    for name in ("README.md", "pyproject.toml", "mkdocs.yml"):
        found += [f"{name}: {m}" for m in outside.findall((REPO / name).read_text("utf-8"))]
    assert not found, found
