"""The generated blocks copied from the checkout's files (``make docs``).

* ``include FILE`` / ``include FILE::NAME``: a file, or one top-level definition of a Python
  file (a function, a class, ``Class.method``, an assignment, or the top-level calls of a
  function of that name), or a scene's suite header (``FILE.xml::suite``), as a code block;
* ``fields MODULE.CLASS``: a dataclass's fields, their defaults and the comments beside
  them in the source.
"""
from __future__ import annotations

import ast
import os
import re
import textwrap

from tools.docs_pages import ROOT, read
from tools.docs_plugins import inline


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
