"""The checks that keep the docs true (run by ``tests/test_docs.py``), as functions of page
texts: each returns a list of problems, one line each, empty when the pages are right.

* :func:`links`: every relative link and anchor resolves;
* :func:`commands`: every ``python -m experiments...`` / ``benchmarks...`` / ``tools...``,
  ``python examples/FILE.py ...`` and ``make ...`` command shown is accepted by its parser
  or Makefile (parse only, nothing runs); inside a section marked
  ``<!-- pending: PATH -->`` (its example file does not exist yet) only the option names;
* :func:`defaults`: every option table's defaults are its parser's (tables of
  :func:`tools.markdown.tables` whose header starts ``option | default``, each after an
  ``<!-- options COMMAND -->`` marker in its section);
  :func:`prose_defaults`: a default stated in prose is the option's default in every
  study; :func:`complete`: every option of every study is in docs/experiments.md;
* :func:`constants`: every ``module.NAME`` stated with its value in brackets is the code's;
* :func:`pending`: a pending section's file really does not exist yet;
* :func:`measured_prose`: no measured ratio (``1.04x``) in hand-written prose;
* :func:`output_files`: every output file the output tables name is written by the code;
* :func:`plugin_tables`: docs/plugins.md's parameter tables are the docstrings'.

The parser checks import the experiments (and the ``--plugin`` files a command names);
run them in a fresh process (``python -m tools.docs_check PAGE ...`` prints their problems),
so that the registries hold what the pages' commands load and nothing else.
"""
from __future__ import annotations

import ast
import glob
import io
import json
import os
import re
import shlex
import sys
from collections import namedtuple
from contextlib import redirect_stderr, redirect_stdout
from urllib.parse import unquote

if __package__:
    from . import docs, markdown
else:                                            # python tools/docs_check.py
    import docs                                  # type: ignore
    import markdown                              # type: ignore

ROOT = docs.ROOT
#: A measured ratio in prose: a decimal number followed by x ("1.04x", "0.54-1.06x").
MEASURED = re.compile(r"(?<![\w.])\d+\.\d+(?:-\d+(?:\.\d+)?)?x\b")
#: A section whose example file does not exist yet: ``<!-- pending: PATH -->``.
PENDING = re.compile(r"<!-- pending: (?P<path>\S+) -->")
#: The command an options table belongs to, written before a hand-made table.
OPTIONS_MARK = re.compile(r"<!-- (?:generated: )?options (?P<command>\S+) -->")
#: Code-block languages whose lines are shell commands.
SHELL = ("sh", "bash", "shell", "console", "")
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


def pending(pages: dict, root: str = ROOT) -> list[str]:
    return [f"{path}:{n}: {p} exists now: replace the pending marker by what it shows "
            f"(an include of the file, make docs) so that its blocks and commands are run"
            for path, text in pages.items() for p, n, _ in pending_sections(text)
            if os.path.exists(os.path.join(root, p))]


# ------------------------------------------------------------------ commands

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


# ------------------------------------------------------------------ option tables

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
            parsers[context] = docs.options(docs.parser_for(context))
        known = parsers[context]
        for k, row in enumerate(table.rows):
            name = _option_name(row[0])
            action = known.get(name)
            where = f"{path}:{table.line + 2 + k}"
            if action is None:
                out.append(f"{where}: {context} has no option {name}")
            elif len(row) < 2 or row[1] != docs.default_cell(action):
                out.append(f"{where}: {context} {name}: the page says "
                           f"{row[1] if len(row) > 1 else '(nothing)'}, the parser's default "
                           f"is {docs.default_cell(action)}")
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
        for option, action in docs.options(docs.parser_for(name)).items():
            cell = docs.default_cell(action)
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
        for option, action in docs.options(docs.parser_for(name)).items():
            cells.setdefault(option, set()).add(docs.default_cell(action))
    out = []
    for path, text in pages.items():
        for n, line in markdown.prose_lines(docs.outside_generated(text)):
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
        lines = dict(markdown.prose_lines(docs.outside_generated(text)))
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
        if os.path.normpath(path) == docs.PLUGINS_PAGE:      # generated whole
            continue
        for n, token in markdown.tokens(docs.outside_generated(text)):
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
    for p in docs.plugin_classes(root):
        want = [(e["name"], docs.inline(e["type"]).strip(), docs.inline(e["default"]).strip())
                for e in docs.parameters(p["doc"])]
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
