"""The documentation stands alone: every link in README.md, CONTRIBUTING.md and docs/ resolves inside the
repository (the file exists; an #anchor names a heading of it), nothing points outside it, no internal issue
numbers, and the README stays a front page (under 150 lines). Pure text: no dolfinx."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from conftest import ROOT

PAGES = sorted([ROOT / "README.md", ROOT / "CONTRIBUTING.md", *(ROOT / "docs").glob("*.md")])
LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^(```|~~~).*?^\1", re.S | re.M)


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped (but - and _), spaces to -."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(page: Path) -> set[str]:
    text = FENCE.sub("", page.read_text())
    out: set[str] = set()
    for heading in re.findall(r"^#{1,6}\s+(.+?)\s*#*\s*$", text, re.M):
        base, n = slug(heading), 0
        while (candidate := base if n == 0 else f"{base}-{n}") in out:
            n += 1
        out.add(candidate)
    out |= set(re.findall(r"<a\s+(?:name|id)=\"([^\"]+)\"", text))
    return out


def links(page: Path) -> list[str]:
    return LINK.findall(FENCE.sub("", page.read_text()))


def test_pages_found() -> None:
    assert {p.name for p in PAGES} >= {"README.md", "CONTRIBUTING.md", "laws.md", "calibration.md", "verify.md"}


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_every_link_resolves_in_the_repository(page: Path) -> None:
    broken = []
    for target in links(page):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # https:, mailto: ...: outside links are allowed
            continue
        path, _, anchor = target.partition("#")
        resolved = (page.parent / path).resolve() if path else page
        if not resolved.is_relative_to(ROOT) or not resolved.exists():
            broken.append(f"{target}: no such file in the repository")
        elif anchor and resolved.suffix == ".md" and anchor not in anchors(resolved):
            broken.append(f"{target}: no heading #{anchor} in {resolved.relative_to(ROOT)}")
    assert not broken, f"{page.relative_to(ROOT)}: " + "; ".join(broken)


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_no_reference_outside_the_repository_or_to_internal_issues(page: Path) -> None:
    text = page.read_text()
    assert "../shared" not in text and "shared/design" not in text and "shared/seeds" not in text
    found = re.findall(r"\b[Ii]ssues? \d+|\bstop \d+", text)
    assert not found, f"{page.relative_to(ROOT)}: internal issue numbers {found}"


def test_the_readme_is_a_front_page() -> None:
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) < 150, len(lines)
    text = "\n".join(lines)
    for needed in ("make demo", "make test", "![", "[[material]]", "docs/calibration.md", "CONTRIBUTING.md"):
        assert needed in text, needed
