"""docs/plugins.md, the plugin reference, from the plugins' class docstrings (``make docs``).

Every class of ``integrators/`` whose docstring has a Mitsuba-style
``.. pluginparameters::`` table is a plugin: the page lists each one's parameters (name,
type, default, description) and the docstring's text around them, RST turned into
Markdown (:func:`inline`), as Mitsuba's own plugin reference is made. Read from the
source, no import.
"""
from __future__ import annotations

import ast
import glob
import os
import re
import textwrap

from tools import markdown
from tools.docs_pages import ROOT

#: The plugin sources, in the order of the reference: integrators, BSDFs, samplers.
KINDS = ("integrator", "bsdf", "sampler")

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
