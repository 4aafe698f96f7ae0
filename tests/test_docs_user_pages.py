"""The user's pages say what holds; the history is in docs/changelog.md (issue 42 item 8).

Property verified: no page of the docs site a user reads (every docs/*.md and
docs/commands/*.md but the changelog, and the gallery's scripts) carries a development
log's marks: an issue number ("(issue 24)", "before issue 30"), a commit hash, or a day
told relative to the writer ("this morning", "the day's merges"). Such marks had been
left inline in performance.md, solver-performance.md, commands/check.md,
commands/diagnose.md and model-json.md after geometry.md was rewritten.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
HISTORY = {"changelog.md"}
MARKS = {
    "an issue number": re.compile(r"\bissues?\s+#?\d+", re.IGNORECASE),
    "a commit hash": re.compile(r"\bcommit\s+`?[0-9a-f]{7,40}\b|`[0-9a-f]{7,12}`"),
    "a day told from the writer's": re.compile(r"\bthis morning\b|\bthe day's\b|\byesterday\b",
                                              re.IGNORECASE),
}


def _user_pages() -> list[Path]:
    pages = sorted(DOCS.glob("*.md")) + sorted(DOCS.glob("commands/*.md"))
    return [p for p in pages if p.name not in HISTORY] + sorted(DOCS.glob("examples/*.py"))


def test_the_marks_are_found():
    """The patterns catch the forms that were on the pages (a test of the test)."""
    for text in ("| target (issue 24) |", "before issue 30's single BLAS thread",
                 "fixed (commit\n`811d268`)", "after the day's merges"):
        assert any(m.search(text) for m in MARKS.values()), text
    assert not any(m.search("ISO 230-3, 25 271 unknowns, sha256 0123456789abcdef0123")
                   for m in MARKS.values())


@pytest.mark.parametrize("page", _user_pages(), ids=lambda p: p.relative_to(DOCS).as_posix())
def test_a_user_page_carries_no_development_log(page):
    text = page.read_text("utf-8")
    found = [f"{what}: line {text.count(chr(10), 0, m.start()) + 1}: {m.group(0)!r}"
             for what, rx in MARKS.items() for m in rx.finditer(text)]
    assert not found, f"{page.relative_to(DOCS)}: " + "; ".join(found)
