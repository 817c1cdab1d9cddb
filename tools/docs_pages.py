"""The pages of the docs and their marked parts, shared by the docs generator
(:mod:`tools.docs`) and the docs checks (:mod:`tools.docs_check`).

* which pages there are (README.md, docs/*.md), reading and (atomically) writing them;
* the generated blocks, ``<!-- generated: KEY -->`` ... ``<!-- /generated -->``: finding
  them, replacing their bodies, blanking them to leave the hand-written prose;
* the pending sections, ``<!-- pending: PATH -->``: a section whose example file does not
  exist yet.
"""
from __future__ import annotations

import glob
import os
import re

from tools import markdown

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: A generated block: ``<!-- generated: KEY -->`` ... ``<!-- /generated -->``.
GENERATED = re.compile(r"<!-- generated: (?P<key>[^>]*?) -->\n(?P<body>.*?)<!-- /generated -->",
                       re.DOTALL)
PLUGINS_PAGE = os.path.join("docs", "plugins.md")
BENCH_PAGE = os.path.join("docs", "benchmarks.md")
#: The pages that hold generated blocks (and that the docs test reads).
PAGES = ("README.md", "docs/*.md")
#: A section whose example file does not exist yet: ``<!-- pending: PATH -->``.
PENDING = re.compile(r"<!-- pending: (?P<path>\S+) -->")


def pages(root: str = ROOT) -> list[str]:
    """README.md and every docs/*.md, as paths relative to ``root``."""
    out = []
    for pattern in PAGES:
        out += sorted(os.path.relpath(p, root) for p in glob.glob(os.path.join(root, pattern)))
    return out


def read(path: str, root: str = ROOT) -> str:
    with open(os.path.join(root, path), encoding="utf-8") as f:
        return f.read()


def write(path: str, text: str, root: str = ROOT) -> None:
    """Atomically (a temporary name, then rename)."""
    full = os.path.join(root, path)
    os.makedirs(os.path.dirname(full) or ".", exist_ok=True)
    tmp = f"{full}.tmp{os.getpid()}"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(tmp, full)


# ------------------------------------------------------------------ generated blocks

def generated(text: str) -> list[tuple[str, str, int]]:
    """(key, body, first line of the body) of every generated block."""
    return [(m.group("key"), m.group("body"), text.count("\n", 0, m.start("body")) + 1)
            for m in GENERATED.finditer(text)]


def replace_generated(text: str, render) -> str:
    """``text`` with the body of every generated block replaced by ``render(key)``
    (a string ending in a newline)."""
    def one(m):
        return f"<!-- generated: {m.group('key')} -->\n{render(m.group('key'))}<!-- /generated -->"
    return GENERATED.sub(one, text)


def outside_generated(text: str) -> str:
    """``text`` with every generated block's body blanked (line numbers kept)."""
    return GENERATED.sub(lambda m: m.group(0)[:m.start("body") - m.start()]
                         + "\n" * m.group("body").count("\n") + "<!-- /generated -->", text)


# ------------------------------------------------------------------ pending sections

def pending_sections(text: str) -> list[tuple[str, int, int]]:
    """(path, first line, last line) of each section marked pending: from the marker to
    the next heading of the same or a higher level than the one above the marker."""
    heads = markdown.headings(text)
    lines = text.count("\n") + 1
    out = []
    for n, line in markdown.prose_lines(text):
        m = PENDING.search(line)
        if not m:
            continue
        level = max((lv for ln, lv, _ in heads if ln < n), default=1)
        end = next((ln - 1 for ln, lv, _ in heads if ln > n and lv <= level), lines)
        out.append((m.group("path"), n, end))
    return out


def in_pending(text: str, line: int) -> str | None:
    return next((p for p, a, b in pending_sections(text) if a <= line <= b), None)
