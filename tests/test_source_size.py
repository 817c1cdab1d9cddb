"""Small source files and functions: every Python file of the project's code (integrators/,
experiments/, tools/, benchmarks/, scenes/; not tests/) is read with :mod:`ast`.

* No file is longer than :data:`MAX_FILE_LINES` lines: split it along its concerns.
* No function (method, nested or async function included) is longer than
  :data:`MAX_FUNCTION_LINES` lines, from its ``def`` to its last line
  (``end_lineno - lineno + 1``), unless its docstring says why it is long: the marker
  ``long:`` followed by the reason on the same line, e.g. a docstring line
  ``long: one Dr.Jit loop, whose state must stay in one scope``. The marker without a
  reason, or in a comment, does not count.

Each check has a negative control on synthetic input: a long function without the marker
is reported and with it is not; a file one line over the limit is reported.
"""
from __future__ import annotations

import ast
import os
import re

import pytest

from _paths import ROOT

MAX_FILE_LINES = 500
MAX_FUNCTION_LINES = 60
#: The folders of the project's code that the checks walk (tests/ is not among them).
FOLDERS = ("integrators", "experiments", "tools", "benchmarks", "scenes")
#: A long function's docstring says why: ``long:`` followed by the reason on its line.
LONG_MARKER = re.compile(r"\blong:[ \t]*\S")


def source_files(folder: str, root: str = ROOT) -> list[str]:
    """Every ``.py`` file under ``root/folder``, relative to ``root`` (caches left out)."""
    out = []
    for directory, dirs, names in os.walk(os.path.join(root, folder)):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__" and not d.startswith("."))
        out += [os.path.relpath(os.path.join(directory, n), root)
                for n in sorted(names) if n.endswith(".py")]
    return out


def line_count(source: str) -> int:
    """The lines of ``source``, as ``wc -l`` counts them (a last line without a newline too)."""
    return source.count("\n") + (1 if source and not source.endswith("\n") else 0)


def long_functions(source: str, limit: int = MAX_FUNCTION_LINES) -> list[tuple[str, int, int]]:
    """(name, first line, lines) of every function of ``source`` longer than ``limit`` lines
    whose docstring has no ``long:`` reason (:data:`LONG_MARKER`)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        lines = node.end_lineno - node.lineno + 1
        if lines > limit and not LONG_MARKER.search(ast.get_docstring(node) or ""):
            out.append((node.name, node.lineno, lines))
    return out


def oversized(folder: str, root: str = ROOT) -> tuple[list[str], list[str], int]:
    """(files over :data:`MAX_FILE_LINES`, functions over :data:`MAX_FUNCTION_LINES` without
    a reason, files read) of ``folder``, one line each naming the file and the size."""
    files, functions = [], []
    paths = source_files(folder, root)
    for path in paths:
        with open(os.path.join(root, path), encoding="utf-8") as f:
            source = f.read()
        if line_count(source) > MAX_FILE_LINES:
            files.append(f"{path}: {line_count(source)} lines")
        functions += [f"{path}:{line} {name}: {n} lines" for name, line, n in
                      long_functions(source)]
    return files, functions, len(paths)


# ------------------------------------------------------------------ the checkers

def _function(name: str, body_lines: int, doc: str = "", indent: str = "") -> str:
    doc_line = [f'{indent}    """{doc}"""'] if doc else []
    body = [f"{indent}    x{i} = {i}" for i in range(body_lines)]
    return "\n".join([f"{indent}def {name}():", *doc_line, *body]) + "\n"


def test_a_long_function_without_its_reason_is_reported():
    source = _function("long_one", MAX_FUNCTION_LINES) + _function("short", 3)
    assert long_functions(source) == [("long_one", 1, MAX_FUNCTION_LINES + 1)]
    assert long_functions(_function("exact", MAX_FUNCTION_LINES - 1)) == []
    # methods, nested and async functions count too
    nested = "class A:\n" + _function("method", MAX_FUNCTION_LINES, indent="    ")
    assert [name for name, _, _ in long_functions(nested)] == ["method"]
    inner = _function("outer", 2) + _function("inner", MAX_FUNCTION_LINES, indent="    ")
    assert [name for name, _, _ in long_functions(inner)] == ["outer", "inner"]
    asynchronous = "async " + _function("coroutine", MAX_FUNCTION_LINES)
    assert [name for name, _, _ in long_functions(asynchronous)] == ["coroutine"]


def test_a_long_function_with_its_reason_is_not_reported():
    marked = _function("long_one", MAX_FUNCTION_LINES,
                       "Trace.\n\n    long: one loop whose state stays in one scope.\n    ")
    assert long_functions(marked) == []
    # the marker without a reason, or the reason outside the docstring, does not count
    assert len(long_functions(_function("bare", MAX_FUNCTION_LINES, "long:   "))) == 1
    comment = _function("commented", MAX_FUNCTION_LINES, "Trace.").replace(
        "    x0 = 0", "    # long: a comment is not the docstring\n    x0 = 0")
    assert len(long_functions(comment)) == 1


def test_a_file_over_the_limit_is_reported(tmp_path):
    folder = tmp_path / "synthetic"
    folder.mkdir()
    (folder / "big.py").write_text("".join(f"x{i} = {i}\n" for i in range(MAX_FILE_LINES + 1)))
    (folder / "full.py").write_text("".join(f"y{i} = {i}\n" for i in range(MAX_FILE_LINES)))
    (folder / "long.py").write_text(_function("f", MAX_FUNCTION_LINES))
    (folder / "notes.txt").write_text("z\n" * (MAX_FILE_LINES + 1))      # not Python
    files, functions, read = oversized("synthetic", str(tmp_path))
    assert files == [f"synthetic/big.py: {MAX_FILE_LINES + 1} lines"]
    assert functions == [f"synthetic/long.py:1 f: {MAX_FUNCTION_LINES + 1} lines"]
    assert read == 3
    assert line_count("a\nb") == line_count("a\nb\n") == 2 and line_count("") == 0


# ------------------------------------------------------------------ the tree



def test_the_walk_finds_the_project_code():
    found = {folder: source_files(folder) for folder in FOLDERS}
    assert all(found.values()), found
    assert os.path.join("integrators", "path.py") in found["integrators"]
    assert os.path.join("experiments", "run_all.py") in found["experiments"]
    assert os.path.join("tools", "docs.py") in found["tools"]
    assert not any(p.startswith("tests") for paths in found.values() for p in paths)


@pytest.mark.parametrize("folder", FOLDERS)
def test_no_source_file_is_too_long(folder):
    files, _, read = oversized(folder)
    assert read > 0
    assert not files, f"files over {MAX_FILE_LINES} lines: {files}"


@pytest.mark.parametrize("folder", FOLDERS)
def test_no_function_is_too_long_without_its_reason(folder):
    _, functions, read = oversized(folder)
    assert read > 0
    assert not functions, (f"functions over {MAX_FUNCTION_LINES} lines whose docstring gives "
                           f"no 'long:' reason: {functions}")
