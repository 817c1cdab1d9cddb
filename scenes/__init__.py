"""The bundled Mitsuba scenes, shipped as package data (``cbox.xml``, ``furnace.xml``).

:func:`path` gives a scene's real file path, in the checkout or in an
installed wheel alike (:mod:`importlib.resources`), so Mitsuba can load it
and resolve paths relative to its folder.
"""
from __future__ import annotations

import atexit
import contextlib
from importlib import resources

#: The scene files in this package.
NAMES = ("cbox.xml", "furnace.xml")

_files = contextlib.ExitStack()
atexit.register(_files.close)
_paths: dict[str, str] = {}


def path(name: str) -> str:
    """The file path of the bundled scene ``name`` (e.g. ``"cbox.xml"``).

    In an installed package on a file system this is the file itself; from a
    zipped package, a copy that lasts until the interpreter exits.
    """
    if name not in _paths:
        resource = resources.files(__name__).joinpath(name)
        if not resource.is_file():
            raise FileNotFoundError(f"no bundled scene '{name}' (have {', '.join(NAMES)})")
        _paths[name] = str(_files.enter_context(resources.as_file(resource)))
    return _paths[name]
