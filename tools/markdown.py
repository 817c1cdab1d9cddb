"""Reading the project's Markdown pages: code blocks, headings and their anchors, links,
tables, generated blocks, commands shown. One definition of each rule, shared by the docs
generator (:mod:`tools.docs`) and the docs test (``tests/test_docs.py``). Pure functions of
the page text; nothing here imports the project.
"""
from __future__ import annotations

import re
import shlex
from dataclasses import dataclass

#: A generated block: ``<!-- generated: KEY -->`` ... ``<!-- /generated -->``.
GENERATED = re.compile(r"<!-- generated: (?P<key>[^>]*?) -->\n(?P<body>.*?)<!-- /generated -->",
                       re.DOTALL)
#: A section whose example file does not exist yet: ``<!-- pending: PATH -->``.
PENDING = re.compile(r"<!-- pending: (?P<path>\S+) -->")
#: The command an options table belongs to, written before a hand-made table.
OPTIONS_MARK = re.compile(r"<!-- (?:generated: )?options (?P<command>\S+) -->")
#: Code-block languages whose lines are shell commands.
SHELL = ("sh", "bash", "shell", "console", "")

_FENCE = re.compile(r"^(?P<indent> {0,3})(?P<fence>```+)(?P<lang>[\w+-]*)[^\n]*$")
_HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
_LINK = re.compile(r"(?<!\\)!?\[(?P<text>[^\]]*)\]\((?P<target>[^)\s]+)(?:\s+\"[^\"]*\")?\)")
_HTML_ID = re.compile(r"<a\s+(?:name|id)=\"([^\"]+)\"")
_CODE_SPAN = re.compile(r"(?<!`)(`+)(?!`)(.+?)(?<!`)\1(?!`)")


@dataclass(frozen=True)
class Block:
    """A fenced code block: its language, first body line (1-based) and body."""
    lang: str
    line: int
    body: str


def blocks(text: str) -> list[Block]:
    """Every fenced code block of ``text`` (an unclosed fence runs to the end)."""
    out, lines, i = [], text.split("\n"), 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        fence, start, body = m.group("fence"), i + 1, []
        i += 1
        while i < len(lines) and not lines[i].strip().startswith(fence):
            body.append(lines[i])
            i += 1
        out.append(Block(m.group("lang").lower(), start + 1, "\n".join(body)))
        i += 1
    return out


def prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) of every line outside fenced code blocks."""
    out, fence = [], None
    for n, line in enumerate(text.split("\n"), 1):
        m = _FENCE.match(line)
        if fence is None and m:
            fence = m.group("fence")
        elif fence is not None and line.strip().startswith(fence):
            fence = None
        elif fence is None:
            out.append((n, line))
    return out


def code_spans(line: str) -> list[str]:
    return [m.group(2).strip() for m in _CODE_SPAN.finditer(line)]


def without_code_spans(line: str) -> str:
    return _CODE_SPAN.sub("", line)


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: markup dropped, lower case, punctuation other than
    ``-`` and ``_`` removed, spaces to ``-``."""
    text = re.sub(r"<[^>]+>", "", heading)
    text = _LINK.sub(lambda m: m.group("text"), text)
    text = text.replace("`", "").replace("*", "")
    text = re.sub(r"[^\w\- ]", "", text.strip().lower())
    return text.replace(" ", "-")


def headings(text: str) -> list[tuple[int, int, str]]:
    """(line number, level, title) of every heading outside code blocks."""
    out = []
    for n, line in prose_lines(text):
        m = _HEADING.match(line)
        if m:
            out.append((n, len(m.group(1)), m.group(2)))
    return out


def anchors(text: str) -> set[str]:
    """Every anchor of the page: its headings' slugs (a repeated one gets ``-1``, ``-2``,
    ... as on GitHub) and explicit ``<a id="...">`` names."""
    seen: dict[str, int] = {}
    out = set()
    for _, _, title in headings(text):
        s = slug(title)
        k = seen.get(s, 0)
        out.add(s if k == 0 else f"{s}-{k}")
        seen[s] = k + 1
    out.update(m.group(1) for _, line in prose_lines(text) for m in _HTML_ID.finditer(line))
    return out


def links(text: str) -> list[tuple[int, str]]:
    """(line number, target) of every Markdown link and image outside code (code spans
    included: a link inside backticks is text)."""
    return [(n, m.group("target")) for n, line in prose_lines(text)
            for m in _LINK.finditer(without_code_spans(line))]


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


# ------------------------------------------------------------------ tables

@dataclass(frozen=True)
class Table:
    line: int                  # line of the header row
    header: list
    rows: list                 # each a list of cell texts (stripped)
    context: str               # the command of the nearest options marker above, or ""


def _cells(line: str) -> list[str]:
    body = line.strip()
    body = body[1:] if body.startswith("|") else body
    body = body[:-1] if body.endswith("|") and not body.endswith("\\|") else body
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", body)]


def tables(text: str) -> list[Table]:
    """Every pipe table outside code blocks, with the command of the nearest
    ``options COMMAND`` marker above it in the same section (none past a heading)."""
    out, context = [], ""
    lines = prose_lines(text)
    i = 0
    while i < len(lines):
        n, line = lines[i]
        mark = OPTIONS_MARK.search(line)
        if mark:
            context = mark.group("command")
        elif _HEADING.match(line):
            context = ""
        if (line.lstrip().startswith("|") and i + 1 < len(lines)
                and re.fullmatch(r"\s*\|?\s*:?-+:?\s*(\|\s*:?-+:?\s*)*\|?\s*", lines[i + 1][1])):
            header, rows, j = _cells(line), [], i + 2
            while j < len(lines) and lines[j][1].lstrip().startswith("|"):
                rows.append(_cells(lines[j][1]))
                j += 1
            out.append(Table(n, header, rows, context))
            i = j
            continue
        i += 1
    return out


# ------------------------------------------------------------------ commands

@dataclass(frozen=True)
class Command:
    line: int
    argv: tuple               # e.g. ("python", "-m", "experiments.lab", "--quick")
    text: str


def _commands_in(line: str, n: int) -> list[Command]:
    try:
        tokens = shlex.split(line, comments=True)
    except ValueError:
        return []
    out, current = [], []
    for token in tokens + [";"]:
        if token in (";", "&&", "||", "&", "|"):
            while current and re.fullmatch(r"[A-Z_][A-Z0-9_]*=.*", current[0]):
                current = current[1:]          # VAR=value before a command
            if current:
                out.append(Command(n, tuple(current), line.strip()))
            current = []
        else:
            current.append(token)
    return [c for c in out if is_project_command(c.argv)]


def is_project_command(argv) -> bool:
    """``python -m experiments.X ...`` (or ``benchmarks.X``, ``tools.X``), ``python
    examples/FILE.py ...`` or ``make TARGET ...``; placeholders (``experiments.NAME``,
    ``make ...``) are not commands."""
    if not argv:
        return False
    if argv[0] == "make":
        return all(re.fullmatch(r"[a-z][\w-]*|[A-Z_][A-Z0-9_]*=.*", w) for w in argv[1:])
    if len(argv) < 2 or re.fullmatch(r"(\S*/)?python[\d.]*", argv[0]) is None:
        return False
    if argv[1] == "-m":
        return len(argv) >= 3 and re.fullmatch(
            r"(experiments|benchmarks|tools)(\.[a-z_][a-z0-9_]*)+", argv[2]) is not None
    return re.fullmatch(r"examples/[\w/]+\.py", argv[1]) is not None


def commands(text: str) -> list[Command]:
    """Every project command shown: in shell code blocks (``\\`` continuations joined,
    ``$`` prompts and comments dropped) and in inline code spans."""
    out = []
    for block in blocks(text):
        if block.lang not in SHELL:
            continue
        joined, start = "", None
        for k, raw in enumerate(block.body.split("\n")):
            line = re.sub(r"^\s*\$\s+", "", raw)
            start = block.line + k if start is None else start
            if line.rstrip().endswith("\\"):
                joined += line.rstrip()[:-1] + " "
                continue
            out += _commands_in(joined + line, start)
            joined, start = "", None
    for n, line in prose_lines(text):
        for span in code_spans(line):
            out += _commands_in(span, n)
    return out
