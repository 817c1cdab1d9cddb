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

Option defaults are written by :func:`default_cell`, the one rule the docs test reads them
back with. Run in a fresh process (the registries then hold the built-in entries only)::

    python -m tools.docs            # rewrite every generated part
    python -m tools.docs --check    # exit 1 naming every stale part
"""
from __future__ import annotations

import argparse
import ast
import glob
import importlib
import os
import re
import sys
import textwrap

if __package__:
    from . import markdown
else:                                            # python tools/docs.py
    import markdown                              # type: ignore

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: A generated block: ``<!-- generated: KEY -->`` ... ``<!-- /generated -->``.
GENERATED = re.compile(r"<!-- generated: (?P<key>[^>]*?) -->\n(?P<body>.*?)<!-- /generated -->",
                       re.DOTALL)
PLUGINS_PAGE = os.path.join("docs", "plugins.md")
BENCH_PAGE = os.path.join("docs", "benchmarks.md")
#: The pages that hold generated blocks (and that the docs test reads).
PAGES = ("README.md", "docs/*.md")
#: The plugin sources, in the order of the reference: integrators, BSDFs, samplers.
KINDS = ("integrator", "bsdf", "sampler")
NONE_CELL = "—"          # an option without a fixed default (None, or an empty list)
OFF_CELL = "off"         # a flag that is not given
#: A study's option whose meaning is the common one (only its default differs).
SAME_MEANING = "as for every study (its own default)"


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


# ------------------------------------------------------------------ the plugins

_LABEL = re.compile(r"^\.\. _(?P<kind>[a-z]+)-(?P<name>\w+):\s*$")
_DEFAULT = re.compile(r"\s*\(Default:\s*(?P<value>.*?)\)\s*$", re.DOTALL)


def plugin_classes(root: str = ROOT) -> list[dict]:
    """Every plugin class of ``integrators/``: kind, name, source file, class, docstring
    (from the source, no import), in the order of :data:`KINDS`, then file and line."""
    found = []
    for path in sorted(glob.glob(os.path.join(root, "integrators", "*.py"))):
        tree = ast.parse(open(path, encoding="utf-8").read())
        for node in tree.body:
            doc = ast.get_docstring(node) if isinstance(node, ast.ClassDef) else None
            if not doc or ".. pluginparameters::" not in doc:
                continue
            label = next((m for m in map(_LABEL.match, doc.split("\n")) if m), None)
            if label is None:
                raise ValueError(f"{path}: class {node.name} has a pluginparameters table "
                                 f"but no '.. _KIND-NAME:' label")
            found.append({"kind": label.group("kind"), "name": label.group("name"),
                          "file": os.path.relpath(path, root), "class": node.name,
                          "doc": doc})
    order = {k: i for i, k in enumerate(KINDS)}
    return sorted(found, key=lambda p: (order.get(p["kind"], len(KINDS)), p["file"]))


def _directive_body(lines: list[str], start: int) -> tuple[list[str], int]:
    """The indented lines after the directive at ``start`` (blank lines inside kept) and
    the index after them."""
    body, i = [], start + 1
    while i < len(lines) and (not lines[i].strip() or lines[i].startswith(" ")):
        body.append(lines[i])
        i += 1
    while body and not body[-1].strip():
        body.pop()
    return body, i


def parameters(doc: str) -> list[dict]:
    """The ``.. pluginparameters::`` entries of a docstring: name, type, description and
    default (the trailing "(Default: ...)", raw RST)."""
    lines = doc.split("\n")
    start = next(i for i, line in enumerate(lines) if line.strip() == ".. pluginparameters::")
    body, _ = _directive_body(lines, start)
    entries, current = [], None
    for line in textwrap.dedent("\n".join(body)).split("\n"):
        if line.startswith("* - "):
            current = [[line[4:].strip()]]
            entries.append(current)
        elif line.lstrip().startswith("- ") and current is not None and \
                len(line) - len(line.lstrip()) == 2:
            current.append([line.strip()[2:]])
        elif current is not None and line.strip():
            current[-1].append(line.strip())
    out = []
    for entry in entries:
        if len(entry) != 3:
            raise ValueError(f"pluginparameters entry {entry[0][0]!r} has {len(entry)} "
                             f"columns, expected 3 (name, type, description)")
        name, kind, description = (" ".join(cell) for cell in entry)
        m = _DEFAULT.search(description)
        out.append({"name": name, "type": kind, "default": m.group("value") if m else "",
                    "description": description[:m.start()] if m else description})
    return out


def inline(text: str) -> str:
    """RST inline markup as Markdown."""
    text = re.sub(r"``(.+?)``", r"`\1`", text)
    text = re.sub(r":math:`(.+?)`", lambda m: f"${m.group(1)}$", text)
    text = re.sub(r":monosp:`(.+?)`", r"`\1`", text)
    def role(m):                 # :func:`~a.b.c` shows c, :func:`a.b.c` all of it
        name = m.group(1)
        return f"`{name.split('.')[-1] if '~' in m.group(0) else name}`"
    text = re.sub(r":(?:func|class|mod|meth|attr|data):`~?([^`]+?)`", role, text)
    return re.sub(r"\|(\w+)\|", r"\1", text)


def _cell(text: str) -> str:
    return inline(text).replace("|", "\\|").strip()


def _prose(doc: str) -> list[str]:
    """The docstring after its title and parameter table, as Markdown lines (a paragraph
    per line, so that inline markup across line breaks converts whole)."""
    lines = doc.split("\n")
    start = next(i for i, line in enumerate(lines) if line.strip() == ".. pluginparameters::")
    _, i = _directive_body(lines, start)
    out, para = [], []

    def flush():
        if para:
            out.extend([inline(" ".join(p.strip() for p in para)), ""])
            para.clear()

    def code(lang, body):
        out.extend([f"```{lang}", *textwrap.dedent("\n".join(body)).strip("\n").split("\n"),
                    "```", ""])

    while i < len(lines):
        line = lines[i]
        if not line.strip():
            flush()
            i += 1
        elif line.strip() == ".. math::":
            flush()
            body, i = _directive_body(lines, i)
            code("math", body)
        elif line.strip() == ".. tabs::":
            flush()
            body, i = _directive_body(lines, i)
            tabs, k = textwrap.dedent("\n".join(body)).split("\n"), 0
            while k < len(tabs):
                m = re.match(r"\.\. code-tab:: (\w+)", tabs[k])
                if m:
                    body, k = _directive_body(tabs, k)
                    code(m.group(1), body)
                else:
                    k += 1
        elif line.rstrip().endswith("::"):
            para.append(line.rstrip()[:-1])
            flush()
            body, i = _directive_body(lines, i)
            code("python", body)
        else:
            para.append(line)
            i += 1
    flush()
    while out and not out[-1].strip():
        out.pop()
    return out


def _title(doc: str) -> str:
    lines = doc.split("\n")
    for k in range(len(lines) - 1):
        if lines[k].strip() and re.fullmatch(r"-{3,}|={3,}", lines[k + 1].strip()):
            return re.sub(r"\s*\(:monosp:`\w+`\)", "", lines[k].strip())
    return ""


def plugins_page(root: str = ROOT) -> str:
    """docs/plugins.md."""
    found = plugin_classes(root)
    out = ["<!-- generated by `make docs` (python -m tools.docs) from the plugins' class "
           "docstrings: edit those, not this page -->", "",
           "# Plugin reference", "",
           "Every parameter of the bundled Mitsuba plugins, generated from their class "
           "docstrings (the one source; Mitsuba's own plugin reference is made the same "
           "way). Each plugin registers for every JIT variant once `integrators` is "
           "imported (see the [README](../README.md#use-the-plugins)).", ""]
    heading = {p["name"]: f"{p['name']} ({p['kind']})" for p in found}
    out += [f"- [`{p['name']}`](#{markdown.anchors('# ' + heading[p['name']]).pop()}): "
            f"{_title(p['doc'])}" for p in found]
    for p in found:
        out += ["", f"## {heading[p['name']]}", "",
                f"{_title(p['doc'])}: class `{p['class']}` in "
                f"[{p['file']}](../{p['file']}).", "",
                "| parameter | type | default | description |", "|---|---|---|---|"]
        out += [f"| `{e['name']}` | {_cell(e['type'])} | {_cell(e['default'])} | "
                f"{_cell(e['description'])} |" for e in parameters(p["doc"])]
        out += ["", *_prose(p["doc"])]
    return "\n".join(out) + "\n"


# ------------------------------------------------------------------ the parsers

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


# ------------------------------------------------------------------ includes

def _segment(source: str, node) -> str:
    lines = source.split("\n")
    first = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])])
    return textwrap.dedent("\n".join(lines[first - 1:node.end_lineno]))


def _calls(node, name: str) -> bool:
    call = node.value if isinstance(node, ast.Expr) else None
    if not isinstance(call, ast.Call):
        return False
    f = call.func
    return (isinstance(f, ast.Name) and f.id == name) or \
        (isinstance(f, ast.Attribute) and f.attr == name)


def excerpt(path: str, name: str, root: str = ROOT) -> str:
    """The source of ``name`` in the Python file ``path`` (see the module docstring)."""
    source = read(path, root)
    tree = ast.parse(source)
    head, _, member = name.partition(".")
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)) and \
                node.name == head:
            if not member:
                return _segment(source, node)
            for sub in node.body:
                if isinstance(sub, (ast.FunctionDef, ast.AsyncFunctionDef)) and \
                        sub.name == member:
                    return _segment(source, sub)
        if not member and isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if any(isinstance(t, ast.Name) and t.id == head for t in targets):
                return _segment(source, node)
    calls = [_segment(source, n) for n in tree.body if not member and _calls(n, head)]
    if calls:
        return "\n".join(calls)
    raise ValueError(f"{path} has no top-level {name} (a function, class, method, "
                     f"assignment or call): update the include in the docs")


def suite_header(path: str, root: str = ROOT) -> str:
    """The suite header comment of the scene file ``path`` (``<!--`` to ``-->``)."""
    m = re.search(r"<!--\s*\nsuite:.*?-->", read(path, root), re.DOTALL)
    if m is None:
        raise ValueError(f"{path} has no suite header (a comment starting with 'suite:')")
    return m.group(0)


def include_block(spec: str, root: str = ROOT) -> str:
    path, _, name = spec.partition("::")
    if not os.path.isfile(os.path.join(root, path)):
        raise ValueError(f"include {spec}: {path} does not exist")
    if name == "suite" and path.endswith(".xml"):
        text = suite_header(path, root)
    else:
        text = excerpt(path, name, root) if name else read(path, root)
    lang = {".py": "python", ".xml": "xml"}.get(os.path.splitext(path)[1], "")
    return f"```{lang}\n{text.rstrip()}\n```\n"


def fields_table(spec: str, root: str = ROOT) -> str:
    """The fields of the dataclass ``MODULE.CLASS`` (read from its source): name, default,
    and the comment on its line or the ``#:`` lines above it."""
    module, _, name = spec.rpartition(".")
    path = os.path.join(*module.split(".")) + ".py"
    if not os.path.isfile(os.path.join(root, path)):
        path = os.path.join(*module.split("."), "__init__.py")
    source = read(path, root)
    lines = source.split("\n")
    node = next((n for n in ast.parse(source).body
                 if isinstance(n, ast.ClassDef) and n.name == name), None)
    if node is None:
        raise ValueError(f"fields {spec}: {path} has no class {name}")
    rows = ["| field | default | meaning |", "|---|---|---|"]
    for item in node.body:
        if not (isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name)):
            continue
        line = lines[item.lineno - 1]
        comment = line.split("#", 1)[1].strip() if "#" in line else ""
        above, k = [], item.lineno - 2
        while k >= 0 and lines[k].strip().startswith("#:"):
            above.insert(0, lines[k].strip()[2:].strip())
            k -= 1
        meaning = " ".join(above) or comment
        if item.value is None:
            default = "required"
        else:
            value = item.value
            if isinstance(value, ast.Call) and getattr(value.func, "id", "") == "field":
                value = next((kw.value for kw in value.keywords
                              if kw.arg in ("default", "default_factory")), value)
            default = f"`{ast.get_source_segment(source, value)}`"
        rows.append(f"| `{item.target.id}` | {default} | "
                    f"{inline(meaning).replace('|', chr(92) + '|')} |")
    return "\n".join(rows) + "\n"


# ------------------------------------------------------------------ the blocks

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
