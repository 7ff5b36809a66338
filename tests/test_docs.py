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
