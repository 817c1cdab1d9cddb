"""The documentation is true: README.md and docs/*.md checked against the code they describe.

* every relative link and anchor resolves;
* every command shown (``python -m experiments...``, ``benchmarks...``, ``tools...``,
  ``python examples/FILE.py ...``, ``make ...``) is accepted by its parser or the Makefile,
  parsed only, in a fresh process (the ``--plugin`` files a command names are loaded first);
* every Python block of README.md and docs/extending.md runs at the quick settings it is
  written with, in a fresh process from a temporary folder holding a copy of examples/
  (outside the checkout, as a user's own folder), under a deadline;
* every option default stated in a table is the parser's, a default stated in prose
  (`` `--option` (default `V`) ``) is that option's default in every study, and every
  option of every study is in docs/experiments.md;
* every constant stated as `` `module.NAME` (value) `` is the code's;
* the generated parts (docs/plugins.md, option tables, the grammar, the examples shown) are
  what ``make docs`` makes of their sources, and the plugin parameter tables are the
  docstrings', row by row;
* hand-written prose states no measured ratio; the output files the tables name are written
  by the code; a section marked pending names a file that does not exist yet.

The checks are :mod:`tools.docs_check` (on page texts, with the parser checks of
:mod:`tools.docs_check_commands` and :mod:`tools.docs_check_options`) and :mod:`tools.docs`
(the generator, with its writers ``tools/docs_*.py``). Each has a negative control on a
synthetic page that it must catch, beside a correct line that it must pass.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest

from _paths import ROOT
from tools import docs as D, docs_check as C, docs_pages, docs_plugins, markdown as MD

#: Deadline of one subprocess (a Python block, a parser check), seconds.
DEADLINE = 300
#: The pages whose Python blocks must run.
RUNNABLE = ("README.md", "docs/extending.md")
README_LINES = 200


def read(path: str) -> str:
    with open(os.path.join(ROOT, path), encoding="utf-8") as f:
        return f.read()


PAGES = {p: read(p) for p in D.pages()}


def parser_check(pages: list[str], root: str = ROOT, *options) -> list[str]:
    """The parser checks of :mod:`tools.docs_check` on ``pages`` in a fresh process."""
    proc = subprocess.run([sys.executable, "-m", "tools.docs_check", "--root", root, *options,
                           *pages], cwd=ROOT, capture_output=True, text=True, timeout=DEADLINE)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


# ------------------------------------------------------------------ size and links

def test_readme_is_short():
    lines = PAGES["README.md"].count("\n")
    assert lines <= README_LINES, f"README.md has {lines} lines (at most {README_LINES})"


def test_links_and_anchors_resolve():
    assert C.links(PAGES) == []


def test_negative_control_a_broken_link_or_anchor_is_caught():
    page = ("# Real heading\n\n[ok](extending.md#a-strategy) [ok](#real-heading) "
            "[ok](../tests/test_docs.py) [web](https://localhost/x)\n"
            "[gone](missing.md) [bad](#nowhere) [bad](experiments.md#no-such-section)\n"
            "`[in code](missing-too.md)`\n")
    problems = C.links({"docs/synthetic.md": page})
    assert len(problems) == 3, problems
    for target in ("missing.md", "#nowhere", "experiments.md#no-such-section"):
        assert any(target in p for p in problems), (target, problems)


def test_anchors_follow_github():
    text = "# A `code` Heading: two, parts\n## A `code` Heading: two, parts\n"
    assert MD.anchors(text) == {"a-code-heading-two-parts", "a-code-heading-two-parts-1"}


# ------------------------------------------------------------------ commands and defaults

def test_commands_and_option_tables_agree_with_the_parsers():
    """Every command shown parses; every stated default is the parser's; every option of
    every study is in docs/experiments.md."""
    assert parser_check(list(PAGES)) == []


SYNTHETIC_COMMANDS = """\
# Commands

```sh
python -m experiments.convergence --spp 64 --methods cosine,bsdf
python -m experiments.convergence --no-such-option 3
python -m experiments.convergence --methods bsdf+nee+lattice
python -m experiments.convergence --plugin examples/lattice_sampler.py --methods bsdf+nee+lattice
make run ARGS="--methods cosine --spp 8"
make no-such-target
make run ARGS="--bogus 1"
```

Inline: `python -m experiments.lab --quick`, `python -m experiments.lab --quik`.

Prose: `--out` (default `results`) is right; `--repeats R` (default 2) is wrong in every
study, `--spp` (default `256`) differs between studies, and `--seed` defaults to 0 is not
a form the check reads.

<!-- options experiments.convergence -->
| option | default | meaning |
|---|---|---|
| `--time-budget` | `0.1` | right |
| `--spp` | `999` | wrong default |
| `--no-option` | `1` | not an option |

## No marker

| option | default | meaning |
|---|---|---|
| `--spp` | `256` | a table whose command is unknown |

## Pending

<!-- pending: examples/no_such_example.py -->

```sh
python -m experiments.suite --scenes examples/no_such_folder --quick
python -m experiments.suite --scenes examples/no_such_folder --no-such-flag
```
"""


def test_negative_control_bad_commands_and_wrong_defaults_are_caught(tmp_path):
    (tmp_path / "docs").mkdir()
    shutil.copy(os.path.join(ROOT, "Makefile"), tmp_path / "Makefile")
    (tmp_path / "docs" / "synthetic.md").write_text(SYNTHETIC_COMMANDS)
    common = "<!-- generated: options common -->\n" + D.options_table("common") + \
             "<!-- /generated -->\n"
    (tmp_path / "docs" / "experiments.md").write_text("# Experiments\n\n" + common)
    problems = parser_check(["docs/synthetic.md", "docs/experiments.md"], str(tmp_path))
    synthetic = [p for p in problems if p.startswith("docs/synthetic.md")]
    expected = ["--no-such-option", "convergence --methods bsdf+nee+lattice:",
                "no-such-target", "--bogus", "--quik", "--spp: the page says `999`",
                "no option --no-option", "without an '<!-- options COMMAND -->' marker",
                "--no-such-flag", "--repeats (default `2`)", "--spp (default `256`)",
                "--seed: write a stated default as"]
    for text in expected:
        assert any(text in p for p in synthetic), (text, synthetic)
    assert len(synthetic) == len(expected), synthetic
    # completeness: a page with only the common table lacks every study's own options
    assert any("experiments.convergence --time-budget" in p for p in problems), problems


# ------------------------------------------------------------------ Python blocks

def runnable_blocks() -> list[tuple[str, MD.Block]]:
    out = []
    for page in RUNNABLE:
        text = PAGES[page]
        generated = [(start, start + body.count("\n")) for _, body, start in D.generated(text)]
        for block in MD.blocks(text):
            if block.lang == "python" and not any(a <= block.line <= b for a, b in generated):
                out.append((page, block))
    return out


def run_block(code: str, folder, timeout: float) -> str | None:
    """Run ``code`` as a script in ``folder`` with a fresh interpreter; why it failed, or
    None."""
    script = os.path.join(folder, "block.py")
    with open(script, "w", encoding="utf-8") as f:
        f.write(code + "\n")
    try:
        proc = subprocess.run([sys.executable, script], cwd=folder, capture_output=True,
                              text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"ran past its deadline of {timeout:g} s"
    if proc.returncode != 0:
        return f"exit status {proc.returncode}: {proc.stderr[-2000:]}"
    return None


def user_folder(tmp_path):
    """A folder outside the checkout holding a copy of examples/, as a user's own."""
    shutil.copytree(os.path.join(ROOT, "examples"), tmp_path / "examples")
    return str(tmp_path)


BLOCKS = runnable_blocks()


def test_every_runnable_page_has_python_blocks():
    assert {page for page, _ in BLOCKS} == set(RUNNABLE)


@pytest.mark.parametrize("page, block", BLOCKS, ids=[f"{p}:{b.line}" for p, b in BLOCKS])
def test_python_block_runs(page, block, tmp_path):
    if docs_pages.in_pending(PAGES[page], block.line):
        compile(block.body, f"{page}:{block.line}", "exec")   # its file does not exist yet
        return
    why = run_block(block.body, user_folder(tmp_path), DEADLINE)
    assert why is None, f"{page}:{block.line}: {why}"


def test_negative_control_a_failing_or_hanging_block_is_caught(tmp_path):
    assert run_block("print('fine')", tmp_path, 60) is None
    assert "ZeroDivisionError" in run_block("1 / 0", tmp_path, 60)
    assert "deadline" in run_block("import time\ntime.sleep(30)", tmp_path, 2)


# ------------------------------------------------------------------ generated parts

def test_generated_parts_are_current():
    proc = subprocess.run([sys.executable, "-m", "tools.docs", "--check"], cwd=ROOT,
                          capture_output=True, text=True, timeout=DEADLINE)
    assert proc.returncode == 0, proc.stderr[-3000:]


def test_negative_control_a_hand_edited_generated_part_is_caught(tmp_path):
    shutil.copytree(os.path.join(ROOT, "integrators"), tmp_path / "integrators",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(os.path.join(ROOT, "examples"), tmp_path / "examples")
    (tmp_path / "docs").mkdir()
    plugins = D.plugins_page(str(tmp_path))
    (tmp_path / D.PLUGINS_PAGE).write_text(plugins)
    include = "<!-- generated: include examples/mirror_lobe.py -->\n"
    readme = include + D.include_block("examples/mirror_lobe.py", str(tmp_path)) + \
        "<!-- /generated -->\n"
    (tmp_path / "README.md").write_text(readme)
    assert D.stale(str(tmp_path)) == []
    edited = plugins.replace("| `rr_depth` | int | 5 |", "| `rr_depth` | int | 6 |")
    assert edited != plugins
    (tmp_path / D.PLUGINS_PAGE).write_text(edited)
    (tmp_path / "README.md").write_text(readme.replace("EXPONENT = 20.0", "EXPONENT = 30.0"))
    problems = D.stale(str(tmp_path))
    assert [p.split(":")[0] for p in problems] == ["README.md", D.PLUGINS_PAGE], problems


def test_plugin_tables_are_the_docstrings():
    assert C.plugin_tables(PAGES[D.PLUGINS_PAGE]) == []
    assert {p["name"] for p in docs_plugins.plugin_classes()} >= {"vr_path", "phong", "halton",
                                                                  "zsobol"}


def test_negative_control_a_plugin_table_row_changed_or_dropped_is_caught():
    page = PAGES[D.PLUGINS_PAGE]
    changed = page.replace("| `rr_depth` | int | 5 |", "| `rr_depth` | int | 6 |")
    problems = C.plugin_tables(changed)
    assert len(problems) == 1 and "rr_depth" in problems[0], problems
    row = next(line for line in page.split("\n") if line.startswith("| `exponent` |"))
    problems = C.plugin_tables(page.replace(row + "\n", ""))
    assert any("phong" in p for p in problems), problems


def test_the_parameter_table_reader_reads_the_docstring_form():
    doc = ("T\n-\n\n.. pluginparameters::\n\n * - alpha\n   - |float|\n   - Roughness,\n"
           "     over two lines. (Default: 0.1)\n\n * - name\n   - |string|\n"
           "   - A name. (Default: ``x``)\n\nText.\n")
    assert [(e["name"], e["type"], e["default"]) for e in docs_plugins.parameters(doc)] == [
        ("alpha", "|float|", "0.1"), ("name", "|string|", "``x``")]


# ------------------------------------------------------------------ constants, prose, files

def test_constants_stated_are_the_codes():
    assert C.constants(PAGES) == []


def test_negative_control_a_wrong_constant_is_caught():
    page = ("ε = `metrics.RELMSE_EPS` (0.01) and `lab.points.PAIRS` (((0, 1), (2, 3),\n"
            "(10, 11), (30, 31), (1, 2))); wrong: `metrics.RELMSE_EPS` (0.02), "
            "`metrics.NO_SUCH` (1).\n")
    problems = C.constants({"docs/synthetic.md": page})
    assert len(problems) == 2, problems
    assert "0.02" in problems[0] and "NO_SUCH" in problems[1], problems


def test_no_measured_ratio_in_hand_written_prose():
    assert C.measured_prose(PAGES) == []


def test_negative_control_a_measured_ratio_in_prose_is_caught():
    page = ("mis costs 1.04x path; halton reaches 0.54-1.06x.\n`1.5x in code`\n"
            "<!-- generated: bench -->\n| row | 0.98x |\n<!-- /generated -->\n"
            "a 1024x512 film, 2x2 blocks\n")
    problems = C.measured_prose({"docs/synthetic.md": page})
    assert len(problems) == 2, problems


def test_output_files_named_are_written_by_the_code():
    assert C.output_files(PAGES) == []


def test_negative_control_an_output_file_the_code_never_writes_is_caught():
    page = ("| file | what |\n|---|---|\n| `conclusion_depth<D>.csv` | real |\n"
            "| `no_such_table_anywhere.csv` | made up |\n")
    problems = C.output_files({"docs/synthetic.md": page})
    assert len(problems) == 1 and "no_such_table_anywhere" in problems[0], problems


def test_pending_sections_name_files_that_do_not_exist_yet():
    assert C.pending(PAGES) == []


def test_negative_control_a_pending_marker_on_an_existing_file_is_caught():
    page = ("# A\n\n## B\n\n<!-- pending: examples/mirror_lobe.py -->\n\ntext\n\n"
            "## C\n\n<!-- pending: examples/not_there_yet.py -->\n")
    problems = C.pending({"docs/synthetic.md": page})
    assert len(problems) == 1 and "mirror_lobe.py exists" in problems[0], problems
    assert docs_pages.in_pending(page, 7) == "examples/mirror_lobe.py"
    assert docs_pages.in_pending(page, 3) is None


# ------------------------------------------------------------------ benchmarks page

def test_benchmarks_page_has_its_generated_table(tmp_path):
    blocks = {k: body for k, body, _ in D.generated(PAGES[D.BENCH_PAGE])}
    assert blocks.get("bench", "").startswith("| measure | value | target | holds? |")
    (tmp_path / "docs").mkdir()
    shutil.copy(os.path.join(ROOT, D.BENCH_PAGE), tmp_path / D.BENCH_PAGE)
    D.write_benchmarks("| measure | value |\n|---|---|\n| a | 1 |\n", str(tmp_path))
    text = (tmp_path / D.BENCH_PAGE).read_text()
    assert dict((k, b) for k, b, _ in D.generated(text))["bench"] == \
        "| measure | value |\n|---|---|\n| a | 1 |\n"
    assert text.split("<!-- generated: bench -->")[0] == \
        PAGES[D.BENCH_PAGE].split("<!-- generated: bench -->")[0]
    (tmp_path / D.BENCH_PAGE).write_text("# no block\n")
    with pytest.raises(ValueError, match="no '<!-- generated: bench -->' block"):
        D.write_benchmarks("| x |\n", str(tmp_path))
