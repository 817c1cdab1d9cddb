"""The generated tables read from the command lines' parsers and registries (``make docs``).

* ``options COMMAND``: the options table of ``python -m COMMAND`` (``common``: the options
  every study takes; a study's own table lists the options it adds or whose default or
  meaning differs);
* ``forwarded``: the options ``run_all`` passes on to the studies;
* ``grammar``: the parts of the method grammar, from the strategy and sampler registries.

An option's default is written by :func:`default_cell`, the one rule the docs checks
(:mod:`tools.docs_check_options`) read it back with.
"""
from __future__ import annotations

import argparse
import importlib
import os
import re

from tools.docs_pages import ROOT

NONE_CELL = "—"          # an option without a fixed default (None, or an empty list)
OFF_CELL = "off"         # a flag that is not given
#: A study's option whose meaning is the common one (only its default differs).
SAME_MEANING = "as for every study (its own default)"


def parser_for(command: str):
    """The argparse parser of ``python -m COMMAND`` (``common``: the options every study
    takes, as :func:`experiments.lib.cli.common_parser` gives them)."""
    if command == "common":
        from experiments.lib import cli
        return cli.common_parser("python -m experiments.STUDY", "")
    module = importlib.import_module(command)
    if hasattr(module, "build_parser"):
        return module.build_parser()
    if hasattr(module, "STUDY"):
        return module.STUDY.build_parser()
    raise ValueError(f"python -m {command} has no parser the docs can read "
                     f"(no build_parser, no STUDY)")


def options(parser) -> dict:
    """{first option string: action} of every option but --help."""
    return {a.option_strings[-1] if a.option_strings[-1].startswith("--") else
            a.option_strings[0]: a for a in parser._actions
            if a.option_strings and not isinstance(a, argparse._HelpAction)}


def default_cell(action) -> str:
    """An option's default as the docs' tables write it (and the docs test reads it)."""
    d = action.default
    if isinstance(action, argparse._StoreTrueAction):
        return OFF_CELL if d is False else f"`{d}`"
    if d is None or d == [] or d == ():
        return NONE_CELL
    if isinstance(d, (list, tuple)):
        d = ",".join(map(str, d))
    d = str(d)
    if os.path.isabs(d) and d.startswith(ROOT + os.sep):
        d = os.path.relpath(d, ROOT)
    return f"`{d}`"


def help_cell(action) -> str:
    text = (action.help or "").replace("%%", "%")
    return re.sub(r"\s+", " ", text).replace("|", "\\|").replace("<", "&lt;").strip()


def option_rows(command: str) -> list[tuple[str, str, str]]:
    """(option, default cell, help cell) of the options of ``command`` that its table
    lists: all of them for ``common``; for a study, those that ``common`` lacks or whose
    default or help differs there."""
    mine = options(parser_for(command))
    common = {} if command == "common" else options(parser_for("common"))
    rows = []
    for name, action in mine.items():
        shared = common.get(name)
        if shared is not None and default_cell(shared) == default_cell(action) and \
                help_cell(shared) == help_cell(action):
            continue
        meaning = help_cell(action)
        if shared is not None and help_cell(shared) == meaning:
            meaning = SAME_MEANING
        rows.append((name, default_cell(action), meaning))
    return rows


def options_table(command: str) -> str:
    lines = ["| option | default | meaning |", "|---|---|---|"]
    lines += [f"| `{o}` | {d} | {h} |" for o, d, h in option_rows(command)]
    return "\n".join(lines) + "\n"


def forwarded_table() -> str:
    """What ``run_all`` passes on to the studies (:data:`experiments.run_all.SHARED`,
    :data:`~experiments.run_all.FORWARDED`)."""
    from experiments import run_all

    def names(options) -> str:
        return ", ".join(f"`{o}`" for o in options)
    return "\n".join([
        "| passed on to every study that takes it | options |", "|---|---|",
        f"| always | {names(run_all.SHARED.values())} |",
        f"| when given to run_all (else each study keeps its own default) | "
        f"{names(run_all.FORWARDED.values())} |",
        "| when given to run_all, to the study that declares it | a study's own options "
        "in the table below (`StudySpec.forwarded`) |"]) + "\n"


def grammar_table() -> str:
    from experiments.lib import methods, samplers
    rand = "; ".join(f"`{n}`: " + ", ".join(f"`{r}`" for r in samplers.get(n).randomizations)
                     for n in samplers.names() if samplers.get(n).randomizations)
    return "\n".join([
        "| part | registered now |", "|---|---|",
        "| STRATEGY | " + ", ".join(f"`{s}`" for s in methods.strategies()) + " |",
        "| SAMPLER | " + ", ".join(f"`{s}`" for s in samplers.names())
        + f" (default `{samplers.DEFAULT}`) |",
        f"| RANDOMIZATION | {rand} |"]) + "\n"
