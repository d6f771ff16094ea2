"""The user docs' cross-references resolve.

* Every relative markdown link or image ``[text](file.md#anchor)`` in README.md and docs/*.md
  names a file that exists and, for an anchor into a markdown page, one of that page's headings
  (GitHub's anchors: the heading's text lowercased, punctuation removed, spaces to dashes, a
  repeated heading numbered -1, -2, ...).
* Every mention of an in-between page by section, ``inbetweens.md, *Section*`` or
  ``inbetween-measurements.md, *Section*`` (in docs, README and code comments), names a heading of
  that page (whole or its start) or one of its bold paragraph labels.
"""
import collections
import functools
import pathlib
import re
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
# A link or an image; its text may run over a line break.
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
# A section mention; in code its title may run over a comment line break ('#: ').
MENTION = re.compile(
    r"(?<![\w-])(inbetweens|inbetween-measurements)\.md,\s*(?:#:?[ \t]*)?\*([^*]{1,200}?)\*")


def code_free(text):
    """Lines of markdown text with fenced code blocks and inline code spans blanked."""
    out, inside = [], False
    for line in text.split("\n"):
        if line.lstrip().startswith("```"):
            inside = not inside
            out.append("")
        else:
            out.append("" if inside else re.sub(r"`[^`]*`", "", line))
    return out


@functools.lru_cache(maxsize=None)
def headings(path):
    """The headings' titles of a markdown page, in order (outside code blocks)."""
    out, inside = [], False
    for line in path.read_text(encoding="utf-8").split("\n"):
        if line.lstrip().startswith("```"):
            inside = not inside
        m = None if inside else re.match(r"^#{1,6} +(.*?)\s*#*\s*$", line)
        if m:
            out.append(m.group(1))
    return tuple(out)


@functools.lru_cache(maxsize=None)
def github_anchors(path):
    """The anchors GitHub gives the headings of a markdown page."""
    seen, out = collections.Counter(), set()
    for title in headings(path):
        text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", title)
        base = re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")
        out.add(base if seen[base] == 0 else f"{base}-{seen[base]}")
        seen[base] += 1
    return frozenset(out)


def test_github_anchors_follow_githubs_rule(tmp_path):
    page = tmp_path / "p.md"
    page.write_text("# Edge deviation at g = 16: where (session 28)\n## Tried\n## Tried\n"
                    "## Guarantees (`tests/core/test_placement_*.py`)\n```\n# not a heading\n```\n"
                    "## Four 20k–22k cloths, ×2\n", encoding="utf-8")
    assert github_anchors(page) == {
        "edge-deviation-at-g--16-where-session-28", "tried", "tried-1",
        "guarantees-testscoretest_placement_py", "four-20k22k-cloths-2"}


def relative_links():
    """(where, page, target) of every link and image in the pages that names no URL scheme."""
    for page in PAGES:
        prose = "\n".join(code_free(page.read_text(encoding="utf-8")))
        for m in LINK.finditer(prose):
            target = m.group(1)
            if not re.match(r"[a-z][a-z0-9+.-]*:", target):
                where = f"{page.relative_to(ROOT)}:{prose.count(chr(10), 0, m.start()) + 1}"
                yield where, page, target


LINKS = list(relative_links())


@pytest.mark.parametrize("where, page, target", LINKS, ids=[w for w, _, _ in LINKS])
def test_relative_link_resolves(where, page, target):
    file_, _, anchor = target.partition("#")
    path = (page.parent / file_).resolve() if file_ else page
    assert path.exists(), f"{where}: {target} names no file"
    if anchor and path.suffix == ".md":
        assert anchor in github_anchors(path), f"{where}: {target} names no heading of {file_}"


def bold_labels(path):
    """The bold labels that open paragraphs ('**Two cores.** ...'), without a final period."""
    return {m.group(1) for line in code_free(path.read_text(encoding="utf-8"))
            for m in [re.match(r"^\*\*([^*]+?)\.?\*\*", line)] if m}


def section_mentions():
    """(where, page, title) of every mention of an in-between page by section in tracked files."""
    files = subprocess.run(["git", "-C", str(ROOT), "ls-files", "*.md", "*.py"], check=True,
                           capture_output=True, text=True).stdout.split()
    for name in files:
        path = ROOT / name
        if not path.exists() or path == pathlib.Path(__file__).resolve():   # this file's examples
            continue
        text = path.read_text(encoding="utf-8")
        for m in MENTION.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            title = re.sub(r"\s*\n\s*(?:#:?|//)?\s*", " ", m.group(2)).strip()
            yield f"{name}:{line}", m.group(1) + ".md", title


MENTIONS = list(section_mentions())


@pytest.mark.parametrize("where, page, title", MENTIONS, ids=[w for w, _, _ in MENTIONS])
def test_section_mention_resolves(where, page, title):
    path = ROOT / "docs" / page
    assert path.exists(), f"{where}: docs/{page} does not exist"
    names = list(headings(path)) + sorted(bold_labels(path))
    assert any(n == title or (n.startswith(title) and re.match(r"[:,( ]", n[len(title):]))
               for n in names), f"{where}: {page} has no section *{title}*"
