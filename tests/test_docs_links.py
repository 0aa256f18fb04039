"""The README is a front door and the docs hold together.

- README.md is at most 250 lines;
- every relative link and image in README.md, bags/README.md and docs/*.md
  points at a file that exists and, with ``#anchor``, at a heading (GitHub's
  slug) or an ``id="..."`` in that file;
- the README's command table lists exactly the commands of the registry
  (``./seapup help``, :data:`seapup_bringup.cli.COMMANDS`) with their summaries.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from seapup_bringup.cli import COMMANDS

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, ROOT / "bags" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^```.*?^```", re.S | re.M)
CODE = re.compile(r"`[^`\n]*`")


def prose(text: str) -> str:
    """The text without fenced code blocks and inline code (links there are not links)."""
    return CODE.sub("", FENCE.sub("", text))


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"`|\*\*|\*", "", heading.strip()).lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    text = path.read_text()
    found, seen = set(), {}
    for line in FENCE.sub("", text).splitlines():
        match = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if match:
            base = slug(match.group(1))
            n = seen.get(base, 0)
            seen[base] = n + 1
            found.add(base if n == 0 else f"{base}-{n}")
    found |= set(re.findall(r"""\bid=["']([^"']+)["']""", text))
    return found


def links(path: Path) -> list[str]:
    return [m.group(1) for m in LINK.finditer(prose(path.read_text()))]


def test_the_readme_is_a_front_door():
    lines = README.read_text().count("\n")
    assert lines <= 250, f"README.md has {lines} lines; move depth to docs/ (at most 250)"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_points_at_a_file_and_anchor_that_exist(page):
    broken = []
    for target in links(page):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):   # http:, https:, mailto: -- not checked here
            continue
        file_part, _, anchor = target.partition("#")
        dest = (page.parent / file_part).resolve() if file_part else page
        if not dest.exists():
            broken.append(f"{target}: no such file")
        elif anchor and (dest.is_dir() or anchor not in anchors(dest)):
            broken.append(f"{target}: no anchor #{anchor} in {dest.relative_to(ROOT)}")
    assert broken == [], f"{page.relative_to(ROOT)}: " + "; ".join(broken)


def test_every_page_under_docs_is_linked_from_the_readme():
    linked = {(README.parent / t.partition("#")[0]).resolve() for t in links(README)}
    missing = [p.name for p in sorted((ROOT / "docs").glob("*.md")) if p.resolve() not in linked]
    assert missing == []


def test_the_readme_command_table_is_the_registry():
    text = README.read_text()
    table = text[text.index('<a id="commands"></a>'):]
    rows = dict(re.findall(r"^\| `([\w-]+)` \| (.*?) \| \[", table, re.M))
    expected = {name: entry.summary.replace("|", "\\|") for name, entry in COMMANDS.items()}
    expected["help"] = rows.get("help", "")
    assert set(rows) == set(expected), "regenerate the README's command table from ./seapup help"
    stale = {name: (rows[name], summary) for name, summary in expected.items() if rows[name] != summary}
    assert stale == {}, "regenerate the README's command table from ./seapup help"
