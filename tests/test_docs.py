"""README and docs/: short README with the two Quick start commands, links that resolve,
and no development diary (issues, sessions, earlier versions) in what users read."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", ROOT / "ARCHITECTURE.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\]\(([^)#\s]+)(#[^)\s]*)?\)")


def test_readme_is_short_with_two_quickstart_commands():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 150
    block = text.split("<!-- quickstart -->")[1].split("<!-- /quickstart -->")[0]
    commands = [ln for ln in block.splitlines() if ln.strip() and not ln.startswith("```")]
    assert len(commands) == 2


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_relative_links_resolve(page):
    text = page.read_text(encoding="utf-8")
    missing = [target for target, _ in LINK.findall(text)
               if "://" not in target and not (page.parent / target).exists()]
    assert not missing, missing


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_no_development_diary(page):
    text = page.read_text(encoding="utf-8").lower()
    for phrase in ("issue", "same day", "at the start of this work", "previous version",
                   "this session"):
        assert phrase not in text, f"{page.name} mentions {phrase!r}"


def test_the_diary_test_sees_a_diary(tmp_path):
    page = tmp_path / "p.md"
    page.write_text("The issue's target was met.", encoding="utf-8")
    with pytest.raises(AssertionError):
        test_no_development_diary(page)


def test_readme_library_example_runs_and_keeps_the_mesh_healthy(tmp_path, monkeypatch):
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    code = text.split("## Library")[1].split("```python")[1].split("```")[0]
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)  # our own text, not user input
    assert (tmp_path / "turned.vtu").stat().st_size > 0
    assert namespace["result"].summary()["inverted"] == 0
    assert namespace["opt"].summary()["min_aspect_ratio"] > 0.5


def test_architecture_names_every_module():
    text = (ROOT / "ARCHITECTURE.md").read_text(encoding="utf-8")
    missing = [str(p.relative_to(ROOT)) for p in sorted((ROOT / "meshopt_toolkit").rglob("*.py"))
               if p.name != "__init__.py" and p.name not in text]
    assert not missing


def test_no_issue_numbers_in_code():
    # comments and docstrings say what and why; tracker references belong to the tracker
    pattern = re.compile(r"\bissues? #?\d", re.IGNORECASE)
    found = [f"{p.relative_to(ROOT)}:{i}"
             for folder in ("meshopt_toolkit", "tests", "benchmarks", "examples", "scripts")
             for p in sorted((ROOT / folder).rglob("*.py"))
             for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
             if pattern.search(line)]
    assert not found
