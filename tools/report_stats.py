"""Size of a report directory and how fast its page opens in Chromium (from file://).

    .venv/bin/python tools/report_stats.py [results] [--runs 5]
    .venv/bin/python -m tools.report_stats [results] [--runs 5]

Prints the total size of the directory, of index.html, of the viewer data
(``viewer-data/``) and of the rest, then opens ``index.html`` in headless
Chromium (Debian's, as the tests) ``--runs`` times, each in a fresh browser
context, and reports the median time from navigation start to
DOMContentLoaded, to the load event, and until every viewer in the first
screen has drawn its image, plus how much data the first screen loaded.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys

if __package__:                       # python -m tools.report_stats
    from .ensure_browser import browser_path
else:                                 # python tools/report_stats.py (its folder is sys.path[0])
    from ensure_browser import browser_path

ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]

# Viewers whose box starts inside the first screen must reach data-state=ready.
FIRST_SCREEN_READY = """() => {
  const roots = Array.from(document.querySelectorAll('[data-viewer]'))
    .filter(el => el.getBoundingClientRect().top < window.innerHeight);
  return roots.every(el => el.dataset.state === 'ready' || el.dataset.state === 'failed');
}"""


def tree_size(path: str) -> tuple[int, int]:
    total, count = 0, 0
    for root, _, names in os.walk(path):
        for name in names:
            total += os.path.getsize(os.path.join(root, name))
            count += 1
    return total, count


def mib(n: int) -> str:
    return f"{n / 2**20:.1f} MiB"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("out", nargs="?", default="results")
    p.add_argument("--runs", type=int, default=5)
    args = p.parse_args()
    page_path = os.path.abspath(os.path.join(args.out, "index.html"))
    if not os.path.isfile(page_path):
        sys.exit(f"error: no report at {page_path}")
    total, files = tree_size(args.out)
    data, data_files = tree_size(os.path.join(args.out, "viewer-data"))
    page = os.path.getsize(page_path)
    store_size, _ = tree_size(os.path.join(args.out, "store"))
    print(f"directory {args.out}: {mib(total)} in {files} files; index.html {page / 1024:.0f} KiB; "
          f"viewer data {mib(data)} in {data_files} files; render store (store/, resume cache) "
          f"{mib(store_size)}; other files (EXR, PNG, CSV, ...) "
          f"{mib(total - data - page - store_size)}")

    from playwright.sync_api import sync_playwright
    rows = []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=browser_path(), args=ARGS)
        for _ in range(args.runs):
            context = browser.new_context(viewport={"width": 1280, "height": 900})
            pg = context.new_page()
            errors = []
            pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            pg.goto("file://" + page_path, wait_until="load")
            pg.wait_for_function(FIRST_SCREEN_READY, timeout=60_000)
            ready = pg.evaluate("performance.now()")
            nav = pg.evaluate("(() => { const n = performance.getEntriesByType('navigation')[0];"
                              " return [n.domContentLoadedEventEnd, n.loadEventEnd]; })()")
            srcs = pg.evaluate("Array.from(document.scripts, s => s.getAttribute('src'))"
                               ".filter(s => s && s.includes('viewer-data'))")
            loaded = sum(os.path.getsize(os.path.join(args.out, s)) for s in srcs)
            viewers = pg.evaluate("document.querySelectorAll('[data-viewer]').length")
            rows.append((nav[0], nav[1], ready, (len(srcs), loaded), viewers, len(errors)))
            context.close()
        browser.close()
    med = [statistics.median(r[k] for r in rows) for k in range(3)]
    print(f"Chromium, file://, 1280x900, median of {args.runs}: DOMContentLoaded {med[0]:.0f} ms, "
          f"load {med[1]:.0f} ms, first-screen viewers drawn {med[2]:.0f} ms; "
          f"first screen loaded {rows[0][3][0]} data files ({mib(rows[0][3][1])}) besides the "
          f"page; {rows[0][4]} viewers; "
          f"console errors: {max(r[5] for r in rows)}")


if __name__ == "__main__":
    main()
