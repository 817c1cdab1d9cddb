"""Interactive image comparisons for the HTML report (Python side of the viewer).

:func:`comparison` turns one comparison (a title, labelled linear HDR images
and optionally a reference) into the HTML of one viewer element, and writes
the pixel data it needs. The page side is ``viewer_assets/viewer.js`` and
``viewer.css``, which :func:`install_assets` copies next to the page and
:data:`HEAD` links from its ``<head>``.

Why ``<script>`` files: a report opened from disk (file://) cannot read image
pixels in Chromium (a canvas that draws a file:// image is tainted) and cannot
``fetch`` files, but it may run scripts. Each image and error map is therefore
one content-addressed script ``viewer-data/<id>.js`` holding its values
(zlib-compressed, base64; images as float32 so the pixel readout shows the
EXR value exactly, error maps as float16, half the size) and calling
``VRViewer.blob(id, data)``.
Identical arrays (a reference shown in several comparisons) are written once,
existing files are not rewritten, and viewers load their scripts only when
they come near the viewport, so the page opens fast however many there are.

Error maps: relMSE per pixel and NVIDIA's FLIP (``flip-evaluator``), both from
:mod:`.metrics` (:func:`~.metrics.relmse_map`, :func:`~.metrics.flip`).
"""
from __future__ import annotations

import base64
import hashlib
import html
import json
import math
import os
import re
import zlib
from importlib import resources

import numpy as np

from .files import write_bytes, write_text
from .metrics import check_shapes, flip, relmse_map

#: The page side of the viewer, package data of :mod:`experiments.lib` (read with
#: :mod:`importlib.resources`, so an installed wheel finds it too).
ASSETS_DIR = resources.files(__package__).joinpath("viewer_assets")
ASSETS = ("viewer.js", "viewer.css")
DATA_DIR = "viewer-data"
#: Value types of the data files, as numpy dtypes (little-endian).
DTYPES = {"f32": "<f4", "f16": "<f2"}
F16_MAX = 65504.0
#: The ``<head>`` lines a page with viewers needs (paths relative to the page).
HEAD = '<link rel="stylesheet" href="viewer.css">\n<script src="viewer.js"></script>'
#: Decades of relMSE the colour bar spans below its top.
RELMSE_DECADES = 4


def install_assets(out: str) -> list[str]:
    """Copy viewer.js and viewer.css into ``out`` (next to the page); return their paths."""
    paths = []
    for name in ASSETS:
        data = ASSETS_DIR.joinpath(name).read_bytes()
        path = os.path.join(out, name)
        if _read_bytes(path) != data:
            write_bytes(path, data)
        paths.append(path)
    return paths


def _read_bytes(path: str) -> bytes | None:
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError:
        return None


# -------------------------------------------------------------------- data

def write_blob(out: str, array: np.ndarray, dtype: str = "f32") -> dict:
    """Write ``array`` as ``dtype`` to ``<out>/viewer-data/<id>.js`` (f16: clipped to +-65504).

    The id is a hash of the values, type and shape, so equal arrays share one
    file and an existing file is never rewritten. Returns ``{"id", "src",
    "type"}`` with ``src`` relative to ``out``.
    """
    if dtype not in DTYPES:
        raise ValueError(f"unknown data type {dtype!r}: expected one of {sorted(DTYPES)}")
    values = np.asarray(array, np.float32)
    if dtype == "f16":
        values = np.clip(values, -F16_MAX, F16_MAX)
    values = np.ascontiguousarray(values, dtype=DTYPES[dtype])
    digest = hashlib.sha1(f"{dtype}{values.shape}".encode() + values.tobytes()).hexdigest()[:20]
    src = f"{DATA_DIR}/{digest}.js"
    path = os.path.join(out, DATA_DIR, digest + ".js")
    if not os.path.exists(path):
        payload = base64.b64encode(zlib.compress(values.tobytes(), 6)).decode("ascii")
        write_text(path, f'VRViewer.blob("{digest}","{payload}");\n')
    return {"id": digest, "src": src, "type": dtype}


def read_blob(out: str, ref: dict, shape) -> np.ndarray:
    """The array a data script holds (the inverse of :func:`write_blob`), as float32."""
    with open(os.path.join(out, ref["src"]), encoding="ascii") as f:
        payload = re.search(r',"([A-Za-z0-9+/=]*)"\);', f.read()).group(1)
    values = np.frombuffer(zlib.decompress(base64.b64decode(payload)), DTYPES[ref["type"]])
    return values.astype(np.float32).reshape(shape)


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")[:40] or "viewer"


def _relmse_range(maps: list[np.ndarray]) -> list[int]:
    """Colour-bar range [lo, hi] in log10 relMSE: hi covers the 99.5th percentile."""
    values = np.concatenate([m.ravel() for m in maps]) if maps else np.zeros(1)
    values = values[np.isfinite(values) & (values > 0)]
    top = float(np.percentile(values, 99.5)) if values.size else 1.0
    hi = math.ceil(math.log10(top)) if top > 0 else 0
    return [hi - RELMSE_DECADES, hi]


def manifest(out: str, title: str, images: list[tuple[str, np.ndarray]],
             reference: np.ndarray | None = None, reference_label: str = "reference",
             notes: list[str] | None = None) -> dict:
    """The viewer's description of one comparison; writes its pixel data under ``out``.

    ``images`` are (label, linear (H, W, 3) array) pairs. With a ``reference``,
    it is shown as the last image and each image gets its relMSE and FLIP maps
    (key ``e`` in the viewer); each label's note then gives the image's mean
    relMSE and FLIP unless ``notes`` (one string per image) is given. The
    manifest is plain JSON data (it can be stored in a report section) and
    refers to the data files by paths relative to ``out``.
    """
    if not images:
        raise ValueError(f"comparison {title!r} has no images")
    if notes is not None and len(notes) != len(images):
        raise ValueError(f"comparison {title!r}: {len(notes)} notes for {len(images)} images")
    shape = np.shape(images[0][1])
    if len(shape) != 3 or shape[2] != 3:
        raise ValueError(f"comparison {title!r}: images must be (H, W, 3), got {shape}")
    for label, image in images:
        if np.shape(image) != shape:
            raise ValueError(f"comparison {title!r}: image {label!r} has shape "
                             f"{np.shape(image)}, the first has {shape}")
    if reference is not None:
        check_shapes(reference, images[0][1])

    entries, relmse_maps = [], []
    for k, (label, image) in enumerate(images):
        entry = {"label": str(label), "data": write_blob(out, image)}
        if reference is not None:
            rel = relmse_map(image, reference)
            flip_map, flip_mean = flip(image, reference)
            relmse_maps.append(rel)
            entry["errors"] = {"relmse": write_blob(out, rel, "f16"),
                               "flip": write_blob(out, flip_map, "f16")}
            entry["stats"] = {"relmse": float(rel.mean()), "flip": flip_mean}
            entry["note"] = f"relMSE {rel.mean():.3g} · FLIP {flip_mean:.3f}"
        if notes is not None:
            entry["note"] = notes[k]
        entries.append(entry)
    if reference is not None:
        zeros = np.zeros(shape[:2], np.float32)
        entries.append({"label": reference_label, "data": write_blob(out, reference),
                        "errors": {"relmse": write_blob(out, zeros, "f16"),
                                   "flip": write_blob(out, zeros, "f16")},
                        "note": "reference", "reference": True})
    result = {"title": title, "width": int(shape[1]), "height": int(shape[0]),
              "images": entries}
    if reference is not None:
        result["ranges"] = {"relmse": _relmse_range(relmse_maps), "flip": [0, 1]}
    return result


def element(manifest: dict, caption: str = "", viewer_id: str | None = None) -> str:
    """HTML of the viewer element for a :func:`manifest` (``data-viewer`` = ``viewer_id``,
    by default made from the title and a hash of the manifest)."""
    if viewer_id is None:
        digest = hashlib.sha1(json.dumps(manifest, sort_keys=True).encode()).hexdigest()[:8]
        viewer_id = f"{_slug(manifest['title'])}-{digest}"
    data = json.dumps(manifest, separators=(",", ":")).replace("</", "<\\/")
    esc = html.escape
    width, height = manifest["width"], manifest["height"]
    return (f'<figure class="vrv" data-viewer="{esc(viewer_id)}">'
            f'<script type="application/json" class="vrv-manifest">{data}</script>'
            f'<div class="vrv-placeholder" style="aspect-ratio: {width} / {height}">'
            f'{esc(manifest["title"])}: loading the viewer (needs JavaScript)</div>'
            f'<figcaption>{esc(caption)}</figcaption></figure>')


def comparison(out: str, title: str, images: list[tuple[str, np.ndarray]],
               reference: np.ndarray | None = None, reference_label: str = "reference",
               caption: str = "", notes: list[str] | None = None,
               viewer_id: str | None = None) -> str:
    """HTML of one viewer element for ``images``: :func:`manifest` then :func:`element`."""
    return element(manifest(out, title, images, reference, reference_label, notes),
                   caption, viewer_id)


def write_page(out: str, title: str, body: str) -> str:
    """A standalone page ``<out>/index.html`` around viewer elements; return its path."""
    install_assets(out)
    page = (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">\n'
            f'<title>{html.escape(title)}</title>\n{HEAD}\n</head>\n'
            f'<body><h1>{html.escape(title)}</h1>\n{body}\n</body></html>\n')
    path = os.path.join(out, "index.html")
    write_text(path, page)
    return path
