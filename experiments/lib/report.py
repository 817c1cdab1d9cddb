"""Per-experiment sections and the HTML report ``<out>/index.html``.

Each experiment writes ``<out>/<name>/section.json`` (and a markdown
``summary.md`` of it) with :func:`write_section`: a title, an order, its
settings, versions, timings and a list of blocks (text, image, table, and
viewer: an interactive image comparison, see :mod:`.viewer`).
:func:`build_report` collects every section found under ``<out>`` into one
self-contained page with relative links, plus a list of every file produced,
so a new experiment only has to write its own section.
"""
from __future__ import annotations

import datetime
import html
import os
import platform
import re
import resource

from . import store
from . import viewer as viewers
from .files import markdown_table, read_json, write_csv, write_json, write_text
from .jobs import cpu_model, cpu_simd

SECTION = "section.json"


def peak_rss_mb() -> float:
    """Peak resident set size of this process so far, in MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def versions(variant: str) -> dict:
    """Software and hardware the results were made with."""
    import drjit as dr
    import mitsuba as mi
    import numpy as np
    info = {"mitsuba": mi.__version__, "drjit": dr.__version__, "variant": variant,
            "python": platform.python_version(), "numpy": np.__version__,
            "CPU": f"{cpu_model()} ({os.cpu_count()} logical cores, {cpu_simd()})",
            "OS": platform.platform()}
    if variant.startswith("llvm"):
        try:
            info["libLLVM"] = ".".join(map(str, dr.detail.llvm_version()))
        except Exception:  # noqa: BLE001
            info["libLLVM"] = "unknown"
        info["DRJIT_LIBLLVM_PATH"] = os.environ.get("DRJIT_LIBLLVM_PATH", "")
    return info


# ---------------------------------------------------------------- blocks

def text(body: str) -> dict:
    return {"kind": "text", "text": body}


def image(src: str, caption: str = "") -> dict:
    return {"kind": "image", "src": src, "caption": caption}


def viewer(out: str, title: str, images: list[tuple[str, object]], reference=None,
           caption: str = "", notes: list[str] | None = None, figure: str = "",
           reference_label: str = "reference") -> dict:
    """An interactive comparison of ``images`` ((label, linear (H, W, 3) array) pairs).

    Writes the viewer's pixel data under ``<out>/viewer-data/`` (``out`` is the
    report directory); with a ``reference`` the viewer also shows relMSE and
    FLIP maps. ``figure``: a static PNG of the same comparison (path relative
    to ``out``), linked under the viewer and shown in the markdown summary.
    See :func:`.viewer.manifest`.
    """
    return {"kind": "viewer", "caption": caption, "figure": figure,
            "manifest": viewers.manifest(out, title, images, reference, reference_label, notes)}


def table(header: list[str], rows: list[list], caption: str = "", files=(),
          collapsed: bool = False) -> dict:
    """A table block; ``collapsed`` shows it folded (for long tables)."""
    return {"kind": "table", "header": header, "rows": rows, "caption": caption,
            "files": list(files), "collapsed": collapsed}


def write_table(out: str, stem: str, header: list[str], rows: list[list],
                caption: str = "", collapsed: bool = False) -> dict:
    """Write ``<out>/<stem>.csv`` and ``.md``; return the table block linking both."""
    write_csv(os.path.join(out, stem + ".csv"), header, rows)
    write_text(os.path.join(out, stem + ".md"), markdown_table(header, rows))
    return table(header, rows, caption, [stem + ".csv", stem + ".md"], collapsed)


def write_section(out: str, name: str, title: str, order: int, settings: dict,
                  blocks: list[dict], variant: str, wall_seconds: float) -> str:
    """Write ``<out>/<name>/section.json`` and ``summary.md``; return the JSON path."""
    section = {"name": name, "title": title, "order": order, "settings": settings,
               "blocks": blocks, "versions": versions(variant),
               "wall_seconds": round(wall_seconds, 2), "peak_rss_mb": round(peak_rss_mb(), 1),
               "finished": datetime.datetime.now().isoformat(timespec="seconds")}
    path = os.path.join(out, name, SECTION)
    write_json(path, section)
    write_text(os.path.join(out, name, "summary.md"), section_markdown(section))
    return path


def section_markdown(section: dict) -> str:
    lines = [f"# {section['title']}", ""]
    for block in section["blocks"]:
        if block["kind"] == "text":
            lines += [block["text"], ""]
        elif block["kind"] == "image":
            lines += [f"![{block['caption']}](../{block['src']})", ""]
        elif block["kind"] == "viewer":
            labels = ", ".join(im["label"] for im in block["manifest"]["images"])
            lines += [f"*Viewer in index.html: {block['manifest']['title']} ({labels}).* "
                      f"{block['caption']}", ""]
            if block["figure"]:
                lines += [f"![{block['manifest']['title']}](../{block['figure']})", ""]
        elif block["kind"] == "table":
            if block["caption"]:
                lines += [f"**{block['caption']}**", ""]
            lines += [markdown_table(block["header"], block["rows"])]
    lines += [f"Wall time {section['wall_seconds']} s, peak RSS {section['peak_rss_mb']} MiB.", ""]
    return "\n".join(lines)


def read_sections(out: str) -> list[dict]:
    sections = []
    for name in sorted(os.listdir(out)) if os.path.isdir(out) else []:
        section = read_json(os.path.join(out, name, SECTION))
        if section is not None:
            sections.append(section)
    return sorted(sections, key=lambda s: (s["order"], s["name"]))


#: The page and its viewer's files, not listed among the results.
PAGE_FILES = ("index.html",) + viewers.ASSETS


#: Folders of intermediate data that a rerun reuses (not results).
CACHE_DIR = "cache"


def produced_files(out: str) -> list[str]:
    """Every result file under ``out`` (relative paths): not the page, its viewer's
    scripts and data (``viewer-data/``), the job store (``store/``, summarised by
    :func:`store_summary`), the reference store (``references/``), caches (any ``cache/`` folder: built-in scenes, the lab's
    finished panels), nor temporaries."""
    from .references import REFERENCES_DIR       # the reference store: like the job store
    found = []
    skip = {viewers.DATA_DIR, store.STORE_DIR, REFERENCES_DIR}
    for root, dirs, names in os.walk(out):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and d != CACHE_DIR and
                         os.path.relpath(os.path.join(root, d), out) not in skip)
        for name in sorted(names):
            rel = os.path.relpath(os.path.join(root, name), out)
            if rel not in PAGE_FILES and not name.startswith(".tmp-"):
                found.append(rel.replace(os.sep, "/"))
    return found


def store_summary(out: str) -> str:
    """One line on the job store: how many finished jobs it holds and their size."""
    root = os.path.join(out, store.STORE_DIR)
    count = size = 0
    for directory, _, names in os.walk(root):
        for name in names:
            if name.endswith(".npz"):
                count += 1
                size += os.path.getsize(os.path.join(directory, name))
    return (f"{store.STORE_DIR}/ holds the {count} finished render jobs "
            f"({size / 2**20:.1f} MiB) that let a rerun of the same command resume; "
            f"delete it to render everything again.")


# ------------------------------------------------------------------ HTML

CSS = """
body { font-family: -apple-system, 'Segoe UI', Helvetica, Arial, sans-serif; margin: 0;
       color: #222; background: #fafafa; line-height: 1.45; }
main { max-width: 1280px; margin: 0 auto; padding: 1.5em 2em 4em; background: #fff;
       box-shadow: 0 0 6px rgba(0,0,0,.08); }
h1 { margin-top: 0; } h3 { margin-bottom: .3em; }
h2 { border-bottom: 2px solid #ddd; padding-bottom: .2em; margin-top: 2em; }
nav ul { columns: 2; } figure { margin: 1em 0; } figcaption { color: #555; font-size: .92em; }
img { max-width: 100%; height: auto; border: 1px solid #ddd; image-rendering: auto; }
figure.vrv img { border: 0; }
table { border-collapse: collapse; margin: .6em 0 1.2em; font-size: .92em; }
th, td { border: 1px solid #ccc; padding: .25em .6em; text-align: right; }
th { background: #f0f0f0; } td:first-child, th:first-child { text-align: left; }
caption { caption-side: top; text-align: left; font-weight: 600; padding-bottom: .3em; }
.meta td { text-align: left; } .files { font-family: monospace; font-size: .85em; columns: 2; }
details { margin: .5em 0; } summary { cursor: pointer; color: #245; }
.note { color: #555; font-size: .9em; }
.findings { border: 2px solid #2a6; background: #f3fbf5; padding: .4em 1.2em; margin: 1em 0; }
.findings h2 { border: 0; margin: .4em 0 .2em; font-size: 1.2em; }
.findings li { margin: .25em 0; }
"""


def _esc(value) -> str:
    return html.escape(str(value))


def _kv_table(data: dict, cls: str = "meta") -> str:
    rows = "".join(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>" for k, v in data.items())
    return f'<table class="{cls}">{rows}</table>'


def _block_html(block: dict) -> str:
    if block["kind"] == "text":
        return "".join(f"<p>{_esc(p)}</p>" for p in block["text"].split("\n\n"))
    if block["kind"] == "image":
        src = _esc(block["src"])
        return (f'<figure><a href="{src}"><img src="{src}" alt="{_esc(block["caption"])}" '
                f'loading="lazy" decoding="async"></a>'
                f'<figcaption>{_esc(block["caption"])}</figcaption></figure>')
    if block["kind"] == "viewer":
        figure = (f'<p class="note">Static figure: <a href="{_esc(block["figure"])}">'
                  f'{_esc(block["figure"])}</a></p>' if block["figure"] else "")
        return viewers.element(block["manifest"], block["caption"]) + figure
    head = "".join(f"<th>{_esc(h)}</th>" for h in block["header"])
    body = "".join("<tr>" + "".join(f"<td>{_esc(c)}</td>" for c in row) + "</tr>"
                   for row in block["rows"])
    links = " ".join(f'<a href="{_esc(f)}">{_esc(os.path.basename(f))}</a>' for f in block["files"])
    links = f'<p class="note">Download: {links}</p>' if links else ""
    if block.get("collapsed"):
        return (f"<details><summary>{_esc(block['caption'])} ({len(block['rows'])} rows)"
                f"</summary><table><thead><tr>{head}</tr></thead><tbody>{body}</tbody>"
                f"</table></details>{links}")
    caption = f"<caption>{_esc(block['caption'])}</caption>" if block["caption"] else ""
    return f"<table>{caption}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>{links}"


def _section_html(section: dict) -> str:
    parts = [f'<section id="{_esc(section["name"])}"><h2>{_esc(section["title"])}</h2>']
    parts += [_block_html(b) for b in section["blocks"]]
    parts.append(f'<h3>Settings</h3>{_kv_table(section["settings"])}'
                 f'<p class="note">Finished {_esc(section["finished"])}; wall time '
                 f'{section["wall_seconds"]} s, peak RSS {section["peak_rss_mb"]} MiB '
                 f'(of the process that ran it).</p>'
                 f'<details><summary>Versions of this run</summary>'
                 f'{_kv_table(section["versions"])}</details></section>')
    return "\n".join(parts)


def _files_html(files: list[str]) -> str:
    groups: dict[str, list[str]] = {}
    for f in files:
        groups.setdefault(f.split("/")[0] if "/" in f else ".", []).append(f)
    parts = []
    for group, members in groups.items():
        items = "".join(f'<li><a href="{_esc(f)}">{_esc(f)}</a></li>' for f in members)
        parts.append(f"<details><summary>{_esc(group)}/ ({len(members)} files)</summary>"
                     f'<ul class="files">{items}</ul></details>')
    return "\n".join(parts)


#: A study's ``summary.json`` may hold a list of sentences under this key: the report shows
#: them in a findings box at the top of the page (computed from the data by the study).
FINDINGS_KEY = "findings"
#: ... and under this one a table that opens the box (``{"header": [...], "rows": [[...]],
#: "figure": path under the output folder or ""}``), the figure beneath it.
FINDINGS_TABLE_KEY = "findings_table"
#: A file named in a finding (a path under the output folder) becomes a link.
_FILE = re.compile(r"\b[\w.-]+(?:/[\w.-]+)*\.(?:csv|md|json|png|pdf|html)\b")


def _linked(sentence: str, out: str) -> str:
    """``sentence`` escaped, each path in it of a file under ``out`` a link to it."""
    parts, last = [], 0
    for match in _FILE.finditer(sentence):
        if not os.path.isfile(os.path.join(out, match.group(0))):
            continue
        parts += [_esc(sentence[last:match.start()]),
                  f'<a href="{_esc(match.group(0))}">{_esc(match.group(0))}</a>']
        last = match.end()
    return "".join(parts) + _esc(sentence[last:])


def _findings_table(table: dict) -> str:
    """A findings box's opening table and figure (:data:`FINDINGS_TABLE_KEY`)."""
    head = "".join(f"<th>{_esc(h)}</th>" for h in table.get("header", []))
    rows = "".join("<tr>" + "".join(f"<td>{_esc(v)}</td>" for v in row) + "</tr>"
                   for row in table.get("rows", []))
    figure = table.get("figure") or ""
    img = (f'<p><a href="{_esc(figure)}"><img src="{_esc(figure)}" alt="{_esc(figure)}" '
           f'style="max-width:100%"></a></p>' if figure else "")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>{img}"


def findings_html(out: str, sections: list[dict]) -> str:
    """The findings boxes of every section whose ``<out>/<name>/summary.json`` has
    :data:`FINDINGS_KEY`, in section order: its :data:`FINDINGS_TABLE_KEY` table and
    figure first, then the sentences (files they name linked)."""
    boxes = []
    for section in sections:
        summary = read_json(os.path.join(out, section["name"], "summary.json"), {})
        items = summary.get(FINDINGS_KEY) if isinstance(summary, dict) else None
        if not items:
            continue
        table = summary.get(FINDINGS_TABLE_KEY)
        rows = "".join(f"<li>{_linked(item, out)}</li>" for item in items)
        boxes.append(f'<div class="findings"><h2>Findings: {_esc(section["title"])}</h2>'
                     + (_findings_table(table) if isinstance(table, dict) else "")
                     + f'<ul>{rows}</ul><p class="note">Computed from the data '
                     f'(<a href="{_esc(section["name"])}/summary.json">'
                     f'{_esc(section["name"])}/summary.json</a>); details in '
                     f'<a href="#{_esc(section["name"])}">its section</a>.</p></div>')
    return "\n".join(boxes)


def build_report(out: str, variant: str) -> str:
    """Write ``<out>/index.html`` from every section under ``out``; return its path."""
    sections = read_sections(out)
    toc = "".join(f'<li><a href="#{_esc(s["name"])}">{_esc(s["title"])}</a></li>'
                  for s in sections)
    body = "\n".join(_section_html(s) for s in sections) or "<p>No experiment has finished yet.</p>"
    produced = produced_files(out)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>Variance reduction in path tracing: experiments</title>
<style>{CSS}</style>
{viewers.HEAD}</head>
<body><main>
<h1>Variance reduction in path tracing: experiments</h1>
<p class="note">Report generated {_esc(datetime.datetime.now().isoformat(timespec="seconds"))}.
Comparisons open in viewers: keys 1-9 or a click on a label pick the image, Space flips
between the last two, the wheel zooms and a drag pans (all images of a comparison together),
+/- change the exposure, e shows the error map (m: relMSE or FLIP), g shows them side by side;
keys act on the viewer under the mouse. Click a chart to open it at full size.</p>
{findings_html(out, sections)}
<nav><ul>{toc}<li><a href="#versions">Versions</a></li>
<li><a href="#files">All files</a></li></ul></nav>
{body}
<section id="versions"><h2>Versions</h2>{_kv_table(versions(variant))}</section>
<section id="files"><h2>All files ({len(produced)})</h2>{_files_html(produced)}
<p class="note">{_esc(store_summary(out))}</p></section>
</main></body></html>
"""
    viewers.install_assets(out)
    path = os.path.join(out, "index.html")
    write_text(path, page)
    return path
