"""The generated parts of the documentation, each from its one source (``make docs``).

* ``docs/plugins.md``, the whole page: the plugins' reference from their class docstrings
  (the Mitsuba-style ``.. pluginparameters::`` tables and the text around them), as
  Mitsuba's own plugin reference is made; every class of ``integrators/`` whose docstring
  has such a table is a plugin.
* Blocks between ``<!-- generated: KEY -->`` and ``<!-- /generated -->`` of README.md and
  docs/*.md, by KEY:

  - ``grammar``: the parts of the method grammar, from the strategy and sampler registries;
  - ``forwarded``: the options ``run_all`` passes on to the studies;
  - ``options COMMAND``: the options table of ``python -m COMMAND`` from its parser
    (``options common``: the options every study takes, with their common defaults; a
    study's own table lists the options it adds or whose default or meaning differs);
  - ``include FILE`` / ``include FILE::NAME``: a file of the checkout, or one top-level
    definition of a Python file (a function, a class, ``Class.method``, an assignment, or
    the top-level calls of a function of that name), or a scene's suite header
    (``FILE.xml::suite``), as a code block;
  - ``fields MODULE.CLASS``: a dataclass's fields, their defaults and the comments beside
    them in the source;
  - ``bench``: the benchmark table, written by ``make bench`` (:func:`write_benchmarks`,
    called by ``benchmarks/run.py``), never regenerated here.

This module dispatches each block to its writer and rewrites or checks the pages; the
writers are :mod:`tools.docs_plugins` (the plugin reference), :mod:`tools.docs_options`
(the tables read from parsers and registries; an option's default is written by its
``default_cell``, the one rule the docs test reads them back with) and
:mod:`tools.docs_include` (includes, dataclass fields); the pages and their blocks are
found by :mod:`tools.docs_pages`. Run in a fresh process (the registries then hold the
built-in entries only)::

    python -m tools.docs            # rewrite every generated part
    python -m tools.docs --check    # exit 1 naming every stale part
"""
from __future__ import annotations

import argparse
import os
import sys

if not __package__:                              # python tools/docs.py: import the package
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tools.docs_include import fields_table, include_block
from tools.docs_options import forwarded_table, grammar_table, options_table
from tools.docs_pages import (BENCH_PAGE, PLUGINS_PAGE, ROOT, generated, pages, read,
                              replace_generated, write)
from tools.docs_plugins import plugins_page


def render(key: str, root: str = ROOT) -> str | None:
    """The body of the generated block ``key``; None for ``bench`` (only ``make bench``
    writes it)."""
    kind, _, arg = key.partition(" ")
    if kind == "grammar":
        return grammar_table()
    if kind == "forwarded":
        return forwarded_table()
    if kind == "options":
        return options_table(arg)
    if kind == "include":
        return include_block(arg, root)
    if kind == "fields":
        return fields_table(arg, root)
    if kind == "bench":
        return None
    raise ValueError(f"unknown generated block '{key}' (grammar, forwarded, options COMMAND, "
                     f"include FILE[::NAME], fields MODULE.CLASS, bench)")


def regenerate(path: str, root: str = ROOT) -> str:
    """The page ``path`` with its generated parts as they should be."""
    if os.path.normpath(path) == PLUGINS_PAGE:
        return plugins_page(root)
    text = read(path, root)
    current = {k: body for k, body, _ in generated(text)}

    def body(key: str) -> str:
        made = render(key, root)
        return current[key] if made is None else made
    return replace_generated(text, body)


def stale(root: str = ROOT) -> list[str]:
    """The pages whose generated parts are out of date (or a reason they cannot be made)."""
    out = []
    wanted = set(pages(root)) | {PLUGINS_PAGE}
    for path in sorted(wanted):
        if not os.path.isfile(os.path.join(root, path)):
            out.append(f"{path}: missing (run: make docs)")
            continue
        try:
            fresh = regenerate(path, root)
        except ValueError as e:
            out.append(f"{path}: {e}")
            continue
        if fresh != read(path, root):
            old = read(path, root).split("\n")
            new = fresh.split("\n")
            line = next((i for i, (a, b) in enumerate(zip(old, new)) if a != b),
                        min(len(old), len(new)))
            out.append(f"{path}: generated text is stale from line {line + 1} "
                       f"(run: make docs)")
    return out


def write_benchmarks(md: str, root: str = ROOT) -> str:
    """Put ``make bench``'s table into the ``bench`` block of docs/benchmarks.md."""
    text = read(BENCH_PAGE, root)
    if not any(k == "bench" for k, _, _ in generated(text)):
        raise ValueError(f"{BENCH_PAGE} has no '<!-- generated: bench -->' block")
    write(BENCH_PAGE, replace_generated(text, lambda k: md if k == "bench" else
                                           dict((a, b) for a, b, _ in generated(text))[k]),
          root)
    return BENCH_PAGE


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.docs", description=__doc__.split("\n")[0])
    p.add_argument("--check", action="store_true",
                   help="change nothing; exit 1 naming every stale generated part")
    args = p.parse_args(argv)
    if args.check:
        problems = stale()
        for line in problems:
            print(line, file=sys.stderr)
        return 1 if problems else 0
    for path in sorted(set(pages()) | {PLUGINS_PAGE}):
        fresh = regenerate(path)
        if not os.path.isfile(os.path.join(ROOT, path)) or fresh != read(path):
            write(path, fresh)
            print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, ROOT)
    sys.exit(main())
