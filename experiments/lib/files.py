"""Files: atomic writes, EXR/PNG/JSON/CSV/NPZ I/O, tone mapping (no other lib module imported).

Every file is written to a temporary name in its own directory and then moved
over the final name with :func:`os.replace`, so an interrupted run (Ctrl-C,
kill) never leaves a half-written file behind.
"""
from __future__ import annotations

import contextlib
import csv
import io
import json
import os

import numpy as np


@contextlib.contextmanager
def atomic_path(path: str):
    """Yield a temporary path next to ``path`` (same extension); on success move it to ``path``."""
    directory, name = os.path.split(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    tmp = os.path.join(directory, f".tmp-{os.getpid()}-{name}")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def write_bytes(path: str, data: bytes) -> None:
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.write(data)


def write_text(path: str, text: str) -> None:
    write_bytes(path, text.encode("utf-8"))


def read_text(path: str) -> str | None:
    """The text in ``path``, or None when it is missing or unreadable."""
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except (OSError, UnicodeDecodeError):
        return None


def write_json(path: str, obj) -> None:
    write_text(path, json.dumps(obj, indent=2, sort_keys=True) + "\n")


def read_json(path: str, default=None):
    """The JSON in ``path``, or ``default`` when it is missing or unreadable."""
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
        return default


def write_csv(path: str, header: list[str], rows: list[list]) -> None:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    write_text(path, buf.getvalue())


def markdown_table(header: list[str], rows: list[list]) -> str:
    """A GitHub-flavoured markdown table."""
    lines = ["| " + " | ".join(map(str, header)) + " |",
             "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(map(str, row)) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def write_npz(path: str, **arrays) -> None:
    with atomic_path(path) as tmp:
        np.savez(tmp, **arrays)


def read_npz(path: str) -> dict | None:
    """The arrays in ``path`` as a dict, or None when it is missing or unreadable."""
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError):
        return None


# ------------------------------------------------------------------ images

def write_exr(path: str, image: np.ndarray) -> None:
    """Write an (H, W, 3) image as a float32 RGB OpenEXR file."""
    import OpenEXR
    rgb = np.ascontiguousarray(image, dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_path(path) as tmp:
        OpenEXR.File(header, {"RGB": rgb}).write(tmp)


def read_exr(path: str) -> np.ndarray:
    """Read an RGB OpenEXR file as an (H, W, 3) float64 array."""
    import OpenEXR
    with OpenEXR.File(path, separate_channels=True) as f:
        channels = f.channels()
        return np.stack([channels[c].pixels for c in "RGB"], axis=-1).astype(np.float64)


def tonemap(image: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Linear radiance to 8-bit sRGB (clipped), (H, W, 3) uint8."""
    x = np.clip(np.nan_to_num(image * exposure), 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(srgb * 255).astype(np.uint8)


def write_png(path: str, image: np.ndarray) -> None:
    """Write a linear (H, W, 3) image as a tone-mapped sRGB PNG."""
    import matplotlib.image
    with atomic_path(path) as tmp:
        matplotlib.image.imsave(tmp, tonemap(image), format="png")


def write_image(stem: str, image: np.ndarray) -> tuple[str, str]:
    """Write ``stem.exr`` and ``stem.png``; return both paths."""
    write_exr(stem + ".exr", image)
    write_png(stem + ".png", image)
    return stem + ".exr", stem + ".png"
