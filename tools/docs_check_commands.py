"""The docs check that every command a page shows would be accepted (run by
``tests/test_docs.py`` through :mod:`tools.docs_check`, in a fresh process).

Every ``python -m experiments...`` / ``benchmarks...`` / ``tools...``, ``python
examples/FILE.py ...`` and ``make ...`` command of a page, in a shell code block or an
inline code span, is parsed by its parser or looked up in the Makefile (parse only,
nothing runs); inside a section marked ``<!-- pending: PATH -->`` (its example file does
not exist yet) only the option names are checked. The parsers import the experiments (and
the ``--plugin`` files a command names).
"""
from __future__ import annotations

import io
import os
import re
import shlex
from collections import namedtuple
from contextlib import redirect_stderr, redirect_stdout

from tools import markdown
from tools.docs_pages import ROOT, in_pending

#: Code-block languages whose lines are shell commands.
SHELL = ("sh", "bash", "shell", "console", "")
#: A command shown: its line, words (e.g. ``("python", "-m", "experiments.lab",
#: "--quick")``) and text.
Command = namedtuple("Command", "line argv text")


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


def shown_commands(text: str) -> list[Command]:
    """Every project command a page shows: in shell code blocks (``\\`` continuations
    joined, ``$`` prompts and comments dropped) and in inline code spans."""
    out = []
    for block in markdown.blocks(text):
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
    for n, token in markdown.tokens(text):
        if token.type == "code_inline":
            out += _commands_in(token.content.strip(), n)
    return out


def makefile_targets(root: str = ROOT) -> dict:
    """{target: [recipe lines]} of the Makefile."""
    targets, current = {}, None
    for line in open(os.path.join(root, "Makefile"), encoding="utf-8").read().split("\n"):
        m = re.match(r"^([A-Za-z][\w-]*)\s*:(?!=)", line)
        if m:
            current = targets.setdefault(m.group(1), [])
        elif line.startswith("\t") and current is not None:
            current.append(line.strip())
        elif line.strip() and not line.startswith("#"):
            current = None
    return targets


def _module_of(argv) -> tuple[str, list]:
    """(module or example file, its arguments) of a ``python`` command line."""
    if argv[1] == "-m":
        return argv[2], list(argv[3:])
    return argv[1], list(argv[2:])


def _source_options(module: str) -> set:
    spec = __import__("importlib.util").util.find_spec(module)
    source = open(spec.origin, encoding="utf-8").read() if spec and spec.origin else ""
    return set(re.findall(r"""["'](--[\w-]+)["']""", source))


def _parser_of(target: str):
    """The parser of a module or example file, or None (then its source is scanned)."""
    if target.endswith(".py"):
        from experiments.lib import extensions
        module = extensions.load(os.path.join(ROOT, target))
    else:
        module = __import__("importlib").import_module(target)
    if hasattr(module, "build_parser"):
        return module.build_parser()
    if hasattr(module, "STUDY"):
        return module.STUDY.build_parser()
    return None


def parse(target: str, args: list, names_only: bool = False) -> str | None:
    """Why ``python -m target args`` (or ``python target args``) would be refused, or None."""
    err = io.StringIO()
    try:
        with redirect_stderr(err), redirect_stdout(io.StringIO()):
            from experiments.lib import cli
            if not names_only:
                cli.load_extensions(args)
            if target == "benchmarks.run":
                from benchmarks import run
                parser, call = None, lambda: run.parse_args(args)          # noqa: E731
            else:
                parser = _parser_of(target)
                call = (lambda: parser.parse_args(args)) if parser else None   # noqa: E731
            if names_only or call is None:
                known = (set(parser._option_string_actions) if parser is not None
                         else _source_options(target)) | {"-h", "--help"}
                bad = [a.split("=", 1)[0] for a in args if a.startswith("--")
                       and a.split("=", 1)[0] not in known]
                return f"unknown option {bad[0]}" if bad else None
            call()
    except SystemExit as e:
        if e.code:
            lines = err.getvalue().strip().splitlines()
            return lines[-1] if lines else f"exit status {e.code}"
    except Exception as e:  # noqa: BLE001  (an import error: the command cannot run)
        return f"{type(e).__name__}: {e}"
    return None


def command(argv, names_only: bool = False, root: str = ROOT) -> str | None:
    """Why the command ``argv`` (a tuple of words) would be refused, or None."""
    if argv[0] == "make":
        targets = makefile_targets(root)
        words = [w for w in argv[1:] if "=" not in w]
        assigned = dict(w.split("=", 1) for w in argv[1:] if "=" in w)
        for target in words or [next(iter(targets))]:
            if target not in targets:
                return f"make has no target '{target}' (targets: {', '.join(targets)})"
            for recipe in targets[target]:
                m = re.search(r"-m (\S+)(.*?)\$\(ARGS\)", recipe)
                if m and "ARGS" in assigned:
                    fixed = shlex.split(m.group(2))
                    why = parse(m.group(1), fixed + shlex.split(assigned["ARGS"]), names_only)
                    if why:
                        return f"make {target} ARGS=...: {why}"
        return None
    return parse(*_module_of(argv), names_only=names_only)


def commands(pages: dict, root: str = ROOT) -> list[str]:
    """Every project command of ``pages`` checked (see the module docstring)."""
    out = []
    for path, text in pages.items():
        for c in shown_commands(text):
            why = command(c.argv, in_pending(text, c.line) is not None, root)
            if why:
                out.append(f"{path}:{c.line}: {c.text}: {why}")
    return out
