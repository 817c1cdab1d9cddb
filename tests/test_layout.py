"""Layout of the experiment code (issue #17): one-way imports inside experiments/lib, small classes.

* Every module of ``experiments/lib``, its subpackages (``studies``, ``sweeps``)
  included, is parsed with :mod:`ast`; every import counts, function-local ones
  included, so an import moved into a function to dodge a cycle is still an
  edge. The graph of imports between lib modules (named by their dotted path
  under lib, ``sweeps.base``; a package by its ``__init__``) must be acyclic
  (data flows one way: plan -> execute -> store -> analyse -> present), and the
  base modules (``clock``, ``files``) import nothing else from lib, and ``jobs`` only
  the clock.
* The same holds for ``tools/``: the graph of imports between its modules (``tools.docs``
  -> ``docs``) is acyclic (``mutants`` -> ``mutant_list`` -> ``mutant``, never back).
* No class in ``experiments/`` is longer than :data:`MAX_CLASS_LINES` lines.
* Nothing in ``experiments/lib`` but ``cli.py`` reads the argparse Namespace (issue 29):
  each study makes its typed settings from it in one place and hands those down.

Each check has a negative control on synthetic input, so a checker that
finds nothing because it looks at nothing fails.
"""
from __future__ import annotations

import ast
import os

from _paths import ROOT

LIB = os.path.join(ROOT, "experiments", "lib")
PACKAGE = "experiments.lib"
TOOLS = os.path.join(ROOT, "tools")
MAX_CLASS_LINES = 250


def lib_modules(folder: str = LIB) -> dict[str, str]:
    """{dotted module name under lib: source path} of every module in experiments/lib and
    its subpackages (a subpackage is its ``__init__``; lib's own ``__init__`` is left out);
    of the package ``folder``, another than lib, likewise."""
    out = {}
    for directory, _, names in os.walk(folder):
        rel = os.path.relpath(directory, folder)
        prefix = "" if rel == "." else rel.replace(os.sep, ".") + "."
        for name in sorted(names):
            if not name.endswith(".py"):
                continue
            module = prefix[:-1] if name == "__init__.py" else prefix + name[:-3]
            if module:
                out[module] = os.path.join(directory, name)
    return out


def _package_of(module: str, path: str, top: str = PACKAGE) -> str:
    """The package a module's relative imports start from (``top``: the package that
    ``module`` is named under)."""
    parent = module if path.endswith("__init__.py") else module.rpartition(".")[0]
    return ".".join(p for p in (top, parent) if p)


def _lib_module(target: str, modules, top: str = PACKAGE) -> str | None:
    """The module of lib, or of the package ``top`` (longest dotted prefix among
    ``modules``) that ``target`` names."""
    if not target.startswith(top + "."):
        return None
    parts = target[len(top) + 1:].split(".")
    for k in range(len(parts), 0, -1):
        if ".".join(parts[:k]) in modules:
            return ".".join(parts[:k])
    return None


def imported_lib_modules(source: str, modules, package: str = PACKAGE,
                         top: str = PACKAGE) -> set[str]:
    """The modules of lib (among ``modules``) that ``source``, a module of ``package``,
    imports anywhere: ``from . import x``, ``from .x import y``, ``import experiments.lib.x``,
    ``from experiments.lib import x``, at module level or inside a function. ``top``:
    another package whose modules ``modules`` are (``tools``)."""
    found = set()
    parts = package.split(".")
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = parts[:len(parts) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            targets = [module] + [f"{module}.{alias.name}" for alias in node.names]
        else:
            continue
        for target in targets:
            module = _lib_module(target, modules, top)
            if module is not None:
                found.add(module)
    return found


def import_graph(folder: str = LIB, top: str = PACKAGE) -> dict[str, set[str]]:
    """{module: the modules it imports} of experiments/lib, or of the package ``top`` in
    ``folder``."""
    modules = lib_modules(folder)
    graph = {}
    for name, path in modules.items():
        with open(path, encoding="utf-8") as f:
            graph[name] = imported_lib_modules(f.read(), modules, _package_of(name, path, top),
                                               top) - {name}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of ``graph`` as a list of nodes (first == last), or None if it is acyclic."""
    state: dict[str, int] = {}          # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                cycle = visit(nxt)
                if cycle:
                    return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            cycle = visit(node)
            if cycle:
                return cycle
    return None


def long_classes(source: str, limit: int = MAX_CLASS_LINES) -> list[tuple[str, int]]:
    """(name, lines) of every class (nested ones too) in ``source`` longer than ``limit``."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ClassDef):
            start = min([node.lineno] + [d.lineno for d in node.decorator_list])
            lines = node.end_lineno - start + 1
            if lines > limit:
                out.append((node.name, lines))
    return out


# ------------------------------------------------------------------ imports

def test_import_checker_sees_every_kind_of_import():
    modules = {"store", "execute", "plan", "methods", "files"}
    source = '''
from __future__ import annotations
import numpy as np
from . import plan as P
from .methods import Depth
import experiments.lib.files

def get():
    from .execute import JobResult          # function-local: still an edge
    from experiments.lib import store
    return JobResult
'''
    assert imported_lib_modules(source, modules) == {"plan", "methods", "files", "execute",
                                                     "store"}
    assert imported_lib_modules("import os\nfrom integrators import qmc\n", modules) == set()
    # relative imports that climb out of lib and back in still name lib's modules
    assert imported_lib_modules("from ..lib import store\n", modules) == {"store"}
    assert imported_lib_modules("from ..lib.plan import Job\n", modules) == {"plan"}
    assert imported_lib_modules("from .. import convergence\n", modules) == set()
    # inside a subpackage: relative imports resolve from it, dotted modules are nodes
    sub = {"metrics", "sweeps", "sweeps.base", "studies", "studies.suite"}
    assert imported_lib_modules("from .. import metrics\nfrom .base import Context\n", sub,
                                "experiments.lib.sweeps") == {"metrics", "sweeps.base"}
    assert imported_lib_modules("from experiments.lib.studies import StudySpec\n"
                                "from experiments.lib.studies.suite import STUDY\n", sub) == \
        {"studies", "studies.suite"}


def test_cycle_finder_reports_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None
    cycle = find_cycle({"methods": {"store"}, "store": {"execute"}, "execute": {"plan"},
                        "plan": {"methods"}, "report": {"store"}})
    assert cycle is not None and cycle[0] == cycle[-1]
    assert set(cycle) == {"methods", "store", "execute", "plan"}
    assert find_cycle({"a": {"a"}}) == ["a", "a"]


def test_lib_imports_flow_one_way():
    graph = import_graph()
    assert {"jobs", "files", "plan", "store", "execute", "methods", "study", "studies",
            "studies.convergence", "sweeps", "sweeps.base"} <= set(graph)
    assert sum(map(len, graph.values())) >= 10, graph        # the checker saw the imports
    cycle = find_cycle(graph)
    assert cycle is None, f"import cycle in experiments/lib: {' -> '.join(cycle)}"


def test_the_import_checker_reads_a_package_other_than_lib():
    modules = {"docs", "docs_pages", "markdown", "mutant", "mutant_list", "mutants"}
    source = '''
import os
from . import markdown
from tools.docs_pages import ROOT, read
import tools.mutant
from experiments.lib import cli

def main():
    from tools.mutant_list import MUTANTS     # function-local: still an edge
    return MUTANTS
'''
    assert imported_lib_modules(source, modules, "tools", "tools") == {
        "markdown", "docs_pages", "mutant", "mutant_list"}
    # the cycle this check exists for: the run imported the list, the list the run's Mutant
    old = {"mutants": imported_lib_modules("from tools.mutant_list import MUTANTS\n",
                                           modules, "tools", "tools"),
           "mutant_list": imported_lib_modules("from tools.mutants import Mutant\n",
                                               modules, "tools", "tools")}
    assert find_cycle(old) in (["mutants", "mutant_list", "mutants"],
                               ["mutant_list", "mutants", "mutant_list"])


def test_tools_imports_flow_one_way():
    graph = import_graph(TOOLS, "tools")
    assert {"docs", "docs_check", "docs_pages", "markdown", "mutants", "mutant_list",
            "mutant"} <= set(graph), set(graph)
    assert sum(map(len, graph.values())) >= 10, graph        # the checker saw the imports
    cycle = find_cycle(graph)
    assert cycle is None, f"import cycle in tools: {' -> '.join(cycle)}"
    assert graph["mutant"] == set() and graph["mutant_list_guiding"] == {"mutant"}, graph
    assert graph["mutant_list_bias"] == graph["mutant_list_adaptive"] == {"mutant"}, graph
    assert graph["mutant_list"] == {"mutant", "mutant_list_guiding", "mutant_list_bias",
                                    "mutant_list_adaptive"}, graph
    assert graph["markdown"] == set() and graph["docs_pages"] == {"markdown"}, graph


def test_base_modules_import_nothing_from_lib():
    graph = import_graph()
    assert graph["clock"] == set(), graph["clock"]
    assert graph["jobs"] <= {"clock"}, graph["jobs"]
    assert graph["files"] == set(), graph["files"]
    # the planner does not read the store nor run anything; the store runs nothing
    assert not graph["plan"] & {"store", "execute", "study"}, graph["plan"]
    assert not graph["store"] & {"execute", "plan", "methods", "study"}, graph["store"]
    assert not graph["methods"] & {"store", "execute", "plan", "study"}, graph["methods"]


# ------------------------------------------------------------------ classes

def test_class_length_checker_reports_a_long_class():
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_CLASS_LINES + 50))
    source = f"@decorator\nclass Big:\n{body}\n\nclass Small:\n    pass\n"
    found = long_classes(source)
    assert [name for name, _ in found] == ["Big"]
    assert found[0][1] == MAX_CLASS_LINES + 52
    nested = "class Outer:\n    class Inner:\n" + "\n".join(
        f"        y{i} = {i}" for i in range(20)) + "\n"
    assert [name for name, _ in long_classes(nested, limit=10)] == ["Outer", "Inner"]


def test_no_class_in_experiments_is_too_long():
    checked, too_long = 0, []
    for directory, _, names in os.walk(os.path.join(ROOT, "experiments")):
        for name in sorted(names):
            if name.endswith(".py"):
                path = os.path.join(directory, name)
                with open(path, encoding="utf-8") as f:
                    source = f.read()
                checked += source.count("\nclass ") + source.startswith("class ")
                too_long += [(os.path.relpath(path, ROOT), c, n) for c, n in long_classes(source)]
    assert checked >= 5                      # the walk found the classes
    assert not too_long, f"classes longer than {MAX_CLASS_LINES} lines: {too_long}"


# ------------------------------------------------------------------ typed settings (issue 29)

#: The modules of experiments/lib that still hand the argparse Namespace down.
NAMESPACE_ALLOWED: set = set()


def namespace_uses(source: str) -> list[tuple[str, int]]:
    """Where a module reads the command line below its entry point: ``getattr(args, ...)``,
    ``argparse.Namespace``, or a :class:`Study` made from ``args``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.args:
            first = node.args[0]
            if (node.func.id in ("getattr", "Study") and isinstance(first, ast.Name)
                    and first.id == "args"):
                found.append((f"{node.func.id}(args", node.lineno))
        if (isinstance(node, ast.Attribute) and node.attr == "Namespace"
                and isinstance(node.value, ast.Name) and node.value.id == "argparse"):
            found.append(("argparse.Namespace", node.lineno))
    return found


def test_namespace_checker_sees_every_use():
    source = ('import argparse\n"""getattr(args, \'x\') in prose is not a use."""\n'
              "def run(args: argparse.Namespace):\n    n = getattr(args, 'repeats', 1)\n"
              "    st = Study(args)\n    ok = getattr(settings, 'x', None), Study(settings)\n")
    uses = sorted(namespace_uses(source), key=lambda u: u[1])
    assert [line for _, line in uses] == [3, 4, 5]
    assert [what for what, _ in uses] == ["argparse.Namespace", "getattr(args", "Study(args"]
    assert namespace_uses("def f(settings):\n    return settings.out\n") == []


def test_no_namespace_below_the_command_line():
    """Nothing in experiments/lib but cli.py reads the Namespace: each study converts it to
    its typed settings in one place (its ``settings_from``) and hands those down."""
    modules = lib_modules()
    found = []
    for module, path in modules.items():
        if module == "cli" or module in NAMESPACE_ALLOWED:
            continue
        with open(path, encoding="utf-8") as f:
            found += [(module, what, line) for what, line in namespace_uses(f.read())]
    assert len(modules) > 30 and "study" in modules and "cli" in modules
    assert not found, f"the Namespace below the command line: {found}"
    assert NAMESPACE_ALLOWED <= set(modules), NAMESPACE_ALLOWED - set(modules)
