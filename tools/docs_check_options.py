"""The docs checks of option defaults against the parsers (run by ``tests/test_docs.py``
through :mod:`tools.docs_check`, in a fresh process).

* :func:`defaults`: every option table's defaults are its parser's (tables of
  :func:`tools.markdown.tables` whose header starts ``option | default``, each after an
  ``<!-- options COMMAND -->`` marker in its section), as
  :func:`tools.docs_options.default_cell` writes them;
* :func:`prose_defaults`: a default stated in prose is the option's default in every study;
* :func:`complete`: every option of every study is in docs/experiments.md.
"""
from __future__ import annotations

import os
import re

from tools import markdown
from tools.docs_options import default_cell, options, parser_for
from tools.docs_pages import ROOT, outside_generated

#: The command an options table belongs to, written before a hand-made table.
OPTIONS_MARK = re.compile(r"<!-- (?:generated: )?options (?P<command>\S+) -->")


def option_tables(pages: dict) -> list[tuple[str, markdown.Table, str]]:
    """(path, table, command) of every options table: the command of the nearest
    ``<!-- options COMMAND -->`` marker above it in its section (none past a heading),
    or ""."""
    out = []
    for path, text in pages.items():
        marks = [(n, m.group("command")) for n, line in markdown.prose_lines(text)
                 for m in OPTIONS_MARK.finditer(line)]
        heads = [n for n, _, _ in markdown.headings(text)]
        for t in markdown.tables(text):
            if [h.lower() for h in t.header[:2]] == ["option", "default"]:
                n, command = max(((n, c) for n, c in marks if n < t.line), default=(0, ""))
                out.append((path, t, "" if any(n < h < t.line for h in heads) else command))
    return out


def _option_name(cell: str) -> str:
    spans = markdown.code_spans(cell)
    return (spans[0] if spans else cell).split()[0] if (spans or cell) else ""


def defaults(pages: dict) -> list[str]:
    """Every option table's rows against its command's parser."""
    out, parsers = [], {}
    for path, table, context in option_tables(pages):
        if not context:
            out.append(f"{path}:{table.line}: an options table without an "
                       f"'<!-- options COMMAND -->' marker above it in its section")
            continue
        if context not in parsers:
            parsers[context] = options(parser_for(context))
        known = parsers[context]
        for k, row in enumerate(table.rows):
            name = _option_name(row[0])
            action = known.get(name)
            where = f"{path}:{table.line + 2 + k}"
            if action is None:
                out.append(f"{where}: {context} has no option {name}")
            elif len(row) < 2 or row[1] != default_cell(action):
                out.append(f"{where}: {context} {name}: the page says "
                           f"{row[1] if len(row) > 1 else '(nothing)'}, the parser's default "
                           f"is {default_cell(action)}")
    return out


def complete(pages: dict, page: str = "docs/experiments.md") -> list[str]:
    """Every option of every study (and of run_all) is in ``page``'s tables: its own, or the
    common one with the same default."""
    tables = {}
    for path, table, context in option_tables({page: pages[page]}):
        tables.setdefault(context, {}).update(
            {_option_name(r[0]): r[1] for r in table.rows if len(r) > 1})
    common = tables.get("common", {})
    out = []
    for name in study_commands():
        mine = tables.get(name, {})
        for option, action in options(parser_for(name)).items():
            cell = default_cell(action)
            if option not in mine and common.get(option) != cell:
                out.append(f"{page}: python -m {name} {option} (default {cell}) is in no "
                           f"options table (make docs writes them)")
    return out


#: A default stated in prose: `` `--option ...` (default `VALUE`) ``.
_PROSE_DEFAULT = re.compile(r"`(--[\w-]+)[^`]*`\s*\(default:?\s+(`[^`]+`|[^)\s]+)\)")
#: Any other way of stating a default right after an option.
_OTHER_DEFAULT = re.compile(r"`(--[\w-]+)[^`]*`[^.;|\n]{0,40}?(?:\(default|default:|"
                            r"defaults? to|default is)")


def study_commands() -> list[str]:
    """run_all and every study that has a command module (experiments/NAME.py)."""
    from experiments.lib import studies
    return ["experiments.run_all"] + [f"experiments.{s.name}" for s in studies.ordered()
                                      if os.path.isfile(os.path.join(
                                          ROOT, "experiments", f"{s.name}.py"))]


def prose_defaults(pages: dict) -> list[str]:
    """A default stated in prose must be that option's default in every study that has the
    option (else it is ambiguous: state it in the study's options table)."""
    cells: dict[str, set] = {}
    for name in study_commands():
        for option, action in options(parser_for(name)).items():
            cells.setdefault(option, set()).add(default_cell(action))
    out = []
    for path, text in pages.items():
        for n, line in markdown.prose_lines(outside_generated(text)):
            if line.lstrip().startswith("|"):
                continue
            found = {m.start(): m for m in _PROSE_DEFAULT.finditer(line)}
            for m in _OTHER_DEFAULT.finditer(line):
                if m.start() not in found:
                    out.append(f"{path}:{n}: {m.group(1)}: write a stated default as "
                               f"`{m.group(1)}` (default `VALUE`), or in an options table")
            for m in found.values():
                option, stated = m.group(1), m.group(2)
                stated = stated if stated.startswith("`") else f"`{stated}`"
                have = cells.get(option)
                if not have:
                    out.append(f"{path}:{n}: no study has an option {option}")
                elif have != {stated}:
                    out.append(f"{path}:{n}: {option} (default {stated}): the studies' "
                               f"defaults are {', '.join(sorted(have))}")
    return out
