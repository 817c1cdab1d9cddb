"""The checks that keep the docs true (run by ``tests/test_docs.py``), as functions of page
texts: each returns a list of problems, one line each, empty when the pages are right.

Here, the checks that read only the pages and the source:

* :func:`links`: every relative link and anchor resolves;
* :func:`constants`: every ``module.NAME`` stated with its value in brackets is the code's;
* :func:`pending`: a pending section's file really does not exist yet;
* :func:`measured_prose`: no measured ratio (``1.04x``) in hand-written prose;
* :func:`output_files`: every output file the output tables name is written by the code;
* :func:`plugin_tables`: docs/plugins.md's parameter tables are the docstrings'.

The checks that need the parsers, gathered by :func:`parser_problems`, are in
:mod:`tools.docs_check_commands` (every ``python -m experiments...`` / ``benchmarks...`` /
``tools...``, ``python examples/FILE.py ...`` and ``make ...`` command shown is accepted by
its parser or Makefile) and :mod:`tools.docs_check_options` (option tables' and prose's
defaults are the parsers', every study's options are in docs/experiments.md). They import
the experiments (and the ``--plugin`` files a command names); run them in a fresh process
(``python -m tools.docs_check PAGE ...`` prints their problems), so that the registries
hold what the pages' commands load and nothing else.
"""
from __future__ import annotations

import ast
import glob
import json
import os
import re
import sys
from urllib.parse import unquote

if not __package__:                              # python tools/docs_check.py: the package
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tools import markdown
from tools.docs_check_commands import commands
from tools.docs_check_options import complete, defaults, prose_defaults
from tools.docs_pages import PLUGINS_PAGE, ROOT, outside_generated, pending_sections
from tools.docs_plugins import inline, parameters, plugin_classes

#: A measured ratio in prose: a decimal number followed by x ("1.04x", "0.54-1.06x").
MEASURED = re.compile(r"(?<![\w.])\d+\.\d+(?:-\d+(?:\.\d+)?)?x\b")
#: Folders searched, in order, for the module of a ``module.NAME`` constant.
CONSTANT_HOMES = ("experiments/lib", "experiments/lib/studies", "experiments/lib/sweeps",
                  "integrators", "experiments", "tools", "benchmarks", "tests")


# ------------------------------------------------------------------ links

def links(pages: dict, root: str = ROOT) -> list[str]:
    """``pages``: {path relative to root: text}. Other pages' anchors are read from
    ``pages`` first, then from disk."""
    out = []
    for path, text in pages.items():
        for line, token in markdown.tokens(text):
            if token.type not in ("link_open", "image"):
                continue
            target = unquote(token.attrGet("href") or token.attrGet("src") or "")
            if re.match(r"[a-z][a-z0-9+.-]*:", target):        # http:, mailto:, ...
                continue
            file, _, anchor = target.partition("#")
            dest = os.path.normpath(os.path.join(os.path.dirname(path), file)) if file else path
            full = os.path.join(root, dest)
            if file and not os.path.exists(full):
                out.append(f"{path}:{line}: link to {target}: {dest} does not exist")
                continue
            if anchor:
                if not dest.endswith(".md"):
                    out.append(f"{path}:{line}: link to {target}: an anchor into a non-page")
                    continue
                other = pages.get(dest)
                if other is None:
                    other = open(full, encoding="utf-8").read()
                if anchor not in markdown.anchors(other):
                    out.append(f"{path}:{line}: link to {target}: {dest} has no heading "
                               f"with anchor #{anchor}")
    return out


# ------------------------------------------------------------------ pending sections

def pending(pages: dict, root: str = ROOT) -> list[str]:
    return [f"{path}:{n}: {p} exists now: replace the pending marker by what it shows "
            f"(an include of the file, make docs) so that its blocks and commands are run"
            for path, text in pages.items() for p, n, _ in pending_sections(text)
            if os.path.exists(os.path.join(root, p))]


# ------------------------------------------------------------------ constants

_CONSTANT = re.compile(r"`((?:\w+\.)+)([A-Z][A-Z0-9_]*)` \(")


def _bracketed(text: str, start: int) -> str | None:
    """The text inside the brackets that open at ``text[start]`` (nesting counted)."""
    depth = 0
    for i in range(start, len(text)):
        depth += {"(": 1, ")": -1}.get(text[i], 0)
        if depth == 0:
            return text[start + 1:i]
    return None


def constant_value(module: str, name: str, root: str = ROOT):
    """The literal value of ``NAME = ...`` at the top of ``module`` (a dotted name under one
    of :data:`CONSTANT_HOMES`), from its source."""
    rel = module.replace(".", "/")
    for home in CONSTANT_HOMES:
        for path in (f"{home}/{rel}.py", f"{home}/{rel}/__init__.py"):
            full = os.path.join(root, path)
            if not os.path.isfile(full):
                continue
            for node in ast.parse(open(full, encoding="utf-8").read()).body:
                targets = (node.targets if isinstance(node, ast.Assign) else
                           [node.target] if isinstance(node, ast.AnnAssign) else [])
                if any(isinstance(t, ast.Name) and t.id == name for t in targets):
                    try:
                        return path, ast.literal_eval(node.value)
                    except ValueError:
                        raise ValueError(f"{path}: {name} is not a literal: state no value "
                                         f"for it") from None
            raise ValueError(f"{path} has no top-level {name}")
    raise ValueError(f"no module {module} under {', '.join(CONSTANT_HOMES)}")


def _same(stated: str, value) -> bool:
    if stated == repr(value) or stated == str(value):
        return True
    try:
        return float(stated) == float(value)
    except (TypeError, ValueError):
        return False


def constants(pages: dict, root: str = ROOT) -> list[str]:
    out = []
    for path, text in pages.items():
        lines = dict(markdown.prose_lines(outside_generated(text)))
        prose = "\n".join(lines.get(n, "") for n in range(1, text.count("\n") + 2))
        for m in _CONSTANT.finditer(prose):
            n = prose.count("\n", 0, m.start()) + 1
            stated = _bracketed(prose, m.end() - 1)
            stated = re.sub(r"\s+", " ", stated) if stated is not None else None
            module, name = m.group(1)[:-1], m.group(2)
            try:
                where, value = constant_value(module, name, root)
            except ValueError as e:
                out.append(f"{path}:{n}: {module}.{name}: {e}")
                continue
            if stated is None or not _same(stated, value):
                out.append(f"{path}:{n}: {module}.{name} is {value!r} in {where}, the page "
                           f"says ({stated})")
    return out


# ------------------------------------------------------------------ prose

def measured_prose(pages: dict) -> list[str]:
    """A measured ratio written by hand: figures belong in generated blocks or the report."""
    out = []
    for path, text in pages.items():
        if os.path.normpath(path) == PLUGINS_PAGE:      # generated whole
            continue
        for n, token in markdown.tokens(outside_generated(text)):
            for m in MEASURED.finditer(token.content if token.type == "text" else ""):
                out.append(f"{path}:{n}: '{m.group(0)}' looks like a measured ratio in "
                           f"hand-written prose: generate it or point to the report")
    return out


def output_files(pages: dict, root: str = ROOT) -> list[str]:
    """The files of tables headed ``file ...`` must be named in the experiments' code (a
    placeholder ``<D>`` stands for any part): the longest literal part of each name."""
    source = "\n".join(open(p, encoding="utf-8").read() for p in
                       glob.glob(os.path.join(root, "experiments", "**", "*.py"), recursive=True))
    out = []
    for path, text in pages.items():
        for table in markdown.tables(text):
            if not table.header or not table.header[0].lower().startswith("file"):
                continue
            for row in table.rows:
                for name in markdown.code_spans(row[0]):
                    stem = os.path.basename(name.rstrip("/"))
                    parts = [p for p in re.split(r"<[^>]*>|\*", os.path.splitext(stem)[0]) if p]
                    longest = max(parts, key=len, default="")
                    if len(longest) >= 3 and longest not in source:
                        out.append(f"{path}:{table.line}: {name}: '{longest}' is written "
                                   f"nowhere in experiments/")
    return out


def plugin_tables(text: str, root: str = ROOT) -> list[str]:
    """docs/plugins.md's parameter tables (per plugin section) against the docstrings."""
    sections = re.split(r"^## ", text, flags=re.MULTILINE)[1:]
    pages = {}
    for section in sections:
        name = section.split()[0]
        for table in markdown.tables("## " + section):
            if table.header[:3] == ["parameter", "type", "default"]:
                pages[name] = [(markdown.code_spans(r[0])[0] if markdown.code_spans(r[0]) else r[0],
                                r[1], r[2]) for r in table.rows]
    out = []
    for p in plugin_classes(root):
        want = [(e["name"], inline(e["type"]).strip(), inline(e["default"]).strip())
                for e in parameters(p["doc"])]
        have = pages.get(p["name"])
        if have is None:
            out.append(f"plugins.md: no parameter table for {p['name']} ({p['file']})")
            continue
        for w, h in zip(want, have):
            if w != h:
                out.append(f"plugins.md: {p['name']} parameter {w[0]}: the docstring "
                           f"({p['file']}) says {w[1:]}, the page {h}")
        if len(want) != len(have):
            out.append(f"plugins.md: {p['name']} has {len(want)} parameters in "
                       f"{p['file']}, the page {len(have)}")
    return out


# ------------------------------------------------------------------ in a fresh process

def parser_problems(pages: dict, root: str = ROOT, completeness: bool = True) -> list[str]:
    """The checks that need the parsers: commands, defaults, completeness."""
    out = complete(pages) if completeness and "docs/experiments.md" in pages else []
    out += defaults(pages) + prose_defaults(pages)   # before commands load --plugin files
    return out + commands(pages, root)


def main(argv=None) -> int:
    """``python -m tools.docs_check [--root DIR] [--no-completeness] PAGE ...``: print the
    parser checks' problems of the pages as JSON."""
    argv = list(sys.argv[1:] if argv is None else argv)
    root, completeness = ROOT, True
    if argv[:1] == ["--root"]:
        root, argv = argv[1], argv[2:]
    if argv[:1] == ["--no-completeness"]:
        completeness, argv = False, argv[1:]
    pages = {p: open(os.path.join(root, p), encoding="utf-8").read() for p in argv}
    print(json.dumps(parser_problems(pages, root, completeness)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
