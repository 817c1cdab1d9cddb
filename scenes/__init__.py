"""The bundled Mitsuba scenes, shipped as package data.

``cbox.xml`` (the writeup's box) and ``furnace.xml`` (the tests' analytic
scene) sit at the top; ``suite/`` holds the scene suite: small scenes that
each isolate one phenomenon, with a machine-readable header that says which
method should win there (see :func:`suite`).

:func:`path` gives a scene's real file path, in the checkout or in an
installed wheel alike (:mod:`importlib.resources`), so Mitsuba can load it
and resolve paths relative to its folder (``suite/cbox.xml`` includes
``../cbox.xml``).
"""
from __future__ import annotations

import atexit
import contextlib
import fnmatch
import math
import re
from dataclasses import dataclass
from importlib import resources

#: The scene files at the top of this package.
NAMES = ("cbox.xml", "furnace.xml")
#: The folder of the scene suite, inside this package.
SUITE = "suite"
#: Keys of a scene's suite header that it must give, and the ones it may give.
HEADER_KEYS = ("isolates", "hypothesis", "favours", "over")
HEADER_OPTIONAL = ("exact", "budget", "methods")
#: Characters of a method-name pattern (``methods``, ``favours``, ``over``): the method
#: grammar's (letters, digits, ``_``, ``+``, ``:``) and :mod:`fnmatch`'s wildcards.
_PATTERN = re.compile(r"[A-Za-z0-9_+:*?\[\]!-]+\Z")

_files = contextlib.ExitStack()
atexit.register(_files.close)
_paths: dict[str, str] = {}


def suite_names() -> list[str]:
    """The suite's scene files as names for :func:`path` (``"suite/cbox.xml"``, ...),
    sorted by file name: every ``*.xml`` in ``suite/``."""
    folder = resources.files(__name__).joinpath(SUITE)
    return sorted(f"{SUITE}/{item.name}" for item in folder.iterdir()
                  if item.name.endswith(".xml") and item.is_file())


def suite() -> list[str]:
    """The file paths of the suite's scenes, in the order of :func:`suite_names`."""
    return [path(name) for name in suite_names()]


def path(name: str) -> str:
    """The file path of the bundled scene ``name`` (``"cbox.xml"``, ``"suite/veach_mis.xml"``).

    In an installed package on a file system this is the file itself, next to
    its siblings. From a zipped package it is a copy of the file alone that
    lasts until the interpreter exits (an ``<include>`` of a sibling, as in
    ``suite/cbox.xml``, then does not resolve).
    """
    if name not in _paths:
        resource = resources.files(__name__).joinpath(*name.split("/"))
        if not resource.is_file():
            raise FileNotFoundError(f"no bundled scene '{name}' (have "
                                    f"{', '.join(NAMES + tuple(suite_names()))})")
        _paths[name] = str(_files.enter_context(resources.as_file(resource)))
    return _paths[name]


# ------------------------------------------------------------ suite headers

@dataclass(frozen=True)
class Header:
    """A scene's suite header: what it isolates and which methods should win there.

    ``favours`` and ``over`` are method-name patterns (:mod:`fnmatch`); the
    hypothesis holds when the most efficient method matching ``favours`` beats
    every method matching ``over``. ``exact`` is the value of every pixel where
    the scene has one (the furnace), else None. ``budget`` scales the suite's
    equal-time budget for this scene (``budget: 8x``, header text; 1 without): a
    scene whose error is ruled by rare samples (caustic fireflies, a light
    smaller than a pixel) needs more of them for a decisive interval.
    ``methods`` are method-name patterns: the scene renders only the run's methods that
    match one (and the run's baseline); empty (no ``methods`` line): every method. A
    scene that isolates what one costly method is for (path guiding, which needs a long
    budget to pay for its training) renders that method and its rivals alone.
    """
    isolates: str
    hypothesis: str
    favours: tuple[str, ...]
    over: tuple[str, ...]
    exact: float | None = None
    budget: float = 1.0
    methods: tuple[str, ...] = ()

    def renders(self, method: str) -> bool:
        """Whether the scene renders the method named ``method`` (its ``methods``
        patterns; every method without them; the baseline is the caller's to keep)."""
        return not self.methods or any(fnmatch.fnmatchcase(method, p) for p in self.methods)


_COMMENT = re.compile(r"<!--(.*?)-->", re.DOTALL)
_ENTRY = re.compile(r"^\s+([a-z_]+):\s*(.*?)\s*$")


def header(file: str) -> Header | None:
    """The suite header of the scene file ``file`` (:func:`parse_header`)."""
    with open(file, encoding="utf-8") as f:
        return parse_header(f.read(), file)


def parse_header(text: str, source: str = "<scene>") -> Header | None:
    """The suite header in the XML ``text``, None where it has none.

    The header is the first comment whose first line is ``suite:``, followed
    by one indented ``key: value`` line per key of :data:`HEADER_KEYS` (and
    optionally :data:`HEADER_OPTIONAL`); pattern lists are comma-separated.
    A header with a line of another form, an unknown, repeated, missing or
    empty key, an ``exact`` that is not a number, a ``budget`` that is not a
    positive factor or a ``methods`` entry that is not a method-name pattern raises
    ValueError naming ``source``.
    """
    for comment in _COMMENT.findall(text):
        lines = [line for line in comment.splitlines() if line.strip()]
        if lines and lines[0].strip() == "suite:":
            break
    else:
        return None
    entries: dict[str, str] = {}
    valid = HEADER_KEYS + HEADER_OPTIONAL
    for line in lines[1:]:
        match = _ENTRY.match(line)
        if not match:
            raise ValueError(f"{source}: suite header line {line.strip()!r} is not an "
                             f"indented 'key: value' line (keys: {', '.join(valid)})")
        key, value = match.groups()
        if key not in valid:
            raise ValueError(f"{source}: unknown suite header key {key!r} "
                             f"(valid: {', '.join(valid)})")
        if key in entries:
            raise ValueError(f"{source}: suite header key {key!r} given twice")
        if not value:
            raise ValueError(f"{source}: suite header key {key!r} is empty")
        entries[key] = value
    missing = [key for key in HEADER_KEYS if key not in entries]
    if missing:
        raise ValueError(f"{source}: suite header lacks {', '.join(missing)} "
                         f"(required: {', '.join(HEADER_KEYS)})")
    exact = entries.get("exact")
    if exact is not None:
        try:
            exact = float(exact)
        except ValueError:
            raise ValueError(f"{source}: suite header 'exact' is {exact!r}, "
                             f"not a number") from None
    return Header(entries["isolates"], entries["hypothesis"], _patterns(entries["favours"]),
                  _patterns(entries["over"]), exact, _budget(entries.get("budget"), source),
                  _methods(entries.get("methods"), source))


def _budget(value: str | None, source: str) -> float:
    """The header's ``budget``: ``Nx`` (or ``N``), N a number in (0, 1000]; 1 without."""
    if value is None:
        return 1.0
    try:
        scale = float(value.removesuffix("x"))
    except ValueError:
        scale = math.nan
    if not 0 < scale <= 1000:
        raise ValueError(f"{source}: suite header 'budget' is {value!r}; give a factor of "
                         f"the suite's equal-time budget such as '4x' (above 0, at most "
                         f"1000x)")
    return scale


def _methods(value: str | None, source: str) -> tuple[str, ...]:
    """The header's ``methods``: comma-separated method-name patterns (none without)."""
    if value is None:
        return ()
    patterns = _patterns(value)
    if not patterns:
        raise ValueError(f"{source}: suite header 'methods' is {value!r}, which names no "
                         f"method; give comma-separated method-name patterns such as "
                         f"'path, bsdf+nee, guided+nee*'")
    for p in patterns:
        if not _PATTERN.match(p):
            raise ValueError(f"{source}: suite header 'methods' entry {p!r} is not a "
                             f"method-name pattern: use letters, digits, '_', '+', ':' "
                             f"and the wildcards '*', '?', '[...]' (e.g. 'guided+nee*')")
    return patterns


def _patterns(value: str) -> tuple[str, ...]:
    return tuple(p.strip() for p in value.split(",") if p.strip())
