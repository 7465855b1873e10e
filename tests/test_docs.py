"""The manual holds together: every relative link of the README and docs/ resolves,
and the README keeps the shape CI and users rely on."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", ROOT / "CHANGELOG.md", ROOT / "recordings" / "README.md"]
PAGES += sorted((ROOT / "docs").glob("*.md"))
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(page: Path) -> None:
    broken = [
        target
        for target in LINK.findall(page.read_text())
        if not target.startswith(("http://", "https://", "mailto:"))
        and not (page.parent / target).exists()
    ]
    assert not broken, f"{page.relative_to(ROOT)} links to missing files: {broken}"


def test_every_docs_page_is_reachable_from_the_readme() -> None:
    readme = ROOT / "README.md"
    linked = {(ROOT / t).resolve() for t in LINK.findall(readme.read_text())}
    for page in (ROOT / "docs").glob("*.md"):
        if page.name.startswith("_"):
            continue  # a working note for the maintainers (e.g. history for the CHANGELOG)
        assert page.resolve() in linked, f"README links no docs page {page.name}"


def test_the_quick_start_has_exactly_two_commands() -> None:
    text = (ROOT / "README.md").read_text()
    block = text.split("## Quick start", 1)[1].split("```sh\n", 1)[1].split("```", 1)[0]
    commands = [line for line in block.splitlines() if line.strip() and not line.startswith("#")]
    assert len(commands) == 2
    assert "pipemap record" in commands[0] and "pytest" in commands[1]
