"""Compare two runs of the experiments (two ``--out`` folders): are the numbers unchanged?

    python -m tools.compare_runs OLD NEW [--ignore REGEX ...]

* Renders: every job of OLD's store is matched by name (its key without the hash, which
  changes with the plugin sources) in NEW's store; a pair with the same sample count must
  have a bit-identical image. Jobs only one run has are counted.
* Tables: every CSV that both runs wrote is compared cell by cell, except the columns whose
  header matches one of the ``--ignore`` regular expressions (the clock's columns, e.g.
  ``seconds``, ``efficiency``); rows are matched in order.

Prints one line per differing file and a summary; exits 1 when anything differs. Rerun NEW
with ``--replay-counts OLD`` so that its equal-time renders take OLD's counts.
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import re
import sys

import numpy as np


def store_images(out: str) -> dict:
    """{job name: (spp, path)} of every finished job in ``out``/store."""
    root, found = os.path.join(out, "store"), {}
    for directory, _, names in os.walk(root):
        for name in names:
            if name.endswith(".npz"):
                path = os.path.join(directory, name)
                key = os.path.relpath(path, root)[:-4]
                with np.load(path) as data:
                    spp = json.loads(str(data["meta"]))["job"]["spp"]
                found[key.rsplit("-", 1)[0]] = (spp, path)
    return found


def compare_images(old: str, new: str) -> dict:
    a, b = store_images(old), store_images(new)
    counts = {"identical": 0, "different": [], "other spp": 0, "only old": 0, "only new": 0}
    for name, (spp, path) in a.items():
        if name not in b:
            counts["only old"] += 1
        elif b[name][0] != spp:
            counts["other spp"] += 1
        else:
            with np.load(path) as x, np.load(b[name][1]) as y:
                if np.array_equal(x["image"], y["image"]):
                    counts["identical"] += 1
                else:
                    counts["different"].append(name)
    counts["only new"] = len(set(b) - set(a))
    return counts


def tables(out: str) -> set:
    return {os.path.relpath(os.path.join(d, n), out) for d, _, names in os.walk(out)
            for n in names if n.endswith(".csv") and "/store/" not in d + "/"}


def read_csv(path: str) -> list[list[str]]:
    with open(path, newline="") as f:
        return list(csv.reader(f))


def compare_table(old: str, new: str, ignore: list) -> list[str]:
    """Differences between two CSVs (header, row count, cells outside ignored columns)."""
    a, b = read_csv(old), read_csv(new)
    if not a or not b or a[0] != b[0]:
        return [f"header {a[:1]} != {b[:1]}"]
    if len(a) != len(b):
        return [f"{len(a) - 1} rows != {len(b) - 1} rows"]
    kept = [i for i, h in enumerate(a[0]) if not any(re.search(p, h) for p in ignore)]
    return [f"row {r} column '{a[0][i]}': {a[r][i]} != {b[r][i]}"
            for r in range(1, len(a)) for i in kept if a[r][i] != b[r][i]]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.compare_runs", description=__doc__.split(
        "\n")[0])
    p.add_argument("old")
    p.add_argument("new")
    p.add_argument("--ignore", action="append", default=[], metavar="REGEX",
                   help="CSV columns (header regex) whose values may differ, e.g. seconds")
    args = p.parse_args(argv)
    for out in (args.old, args.new):
        if not os.path.isdir(out):
            p.error(f"no such folder '{out}': give two --out folders of finished runs")
    images = compare_images(args.old, args.new)
    print(f"renders: {images['identical']} bit-identical, {len(images['different'])} "
          f"different, {images['other spp']} with another spp, {images['only old']} only in "
          f"the old run, {images['only new']} only in the new one")
    for name in images["different"][:20]:
        print(f"  different image: {name}")
    old_tables, new_tables = tables(args.old), tables(args.new)
    differing = 0
    for rel in sorted(old_tables & new_tables):
        diffs = compare_table(os.path.join(args.old, rel), os.path.join(args.new, rel),
                              args.ignore)
        if diffs:
            differing += 1
            print(f"{rel}: {len(diffs)} differences, e.g. {diffs[0]}")
    print(f"tables: {len(old_tables & new_tables) - differing} identical, {differing} "
          f"different (ignoring columns {args.ignore or 'none'}); only in the old run: "
          f"{sorted(old_tables - new_tables) or 'none'}; only in the new: "
          f"{sorted(new_tables - old_tables) or 'none'}")
    return 1 if differing or images["different"] else 0


if __name__ == "__main__":
    sys.exit(main())
