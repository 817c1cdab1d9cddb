"""A researcher's own strategy, sampler, scene set or study: one Python file, loaded by path.

``--plugin FILE`` (any script, repeatable) imports FILE before the command line is parsed,
so whatever it registers (``integrators.register_strategy``,
:func:`experiments.lib.samplers.register_sampler`, :func:`experiments.lib.studies.register_study`,
Mitsuba's ``mi.register_sampler``...) is known to the method grammar, to ``--help`` and to
``run_all``. The Mitsuba variant is set first (``--variant``, default ``llvm_ad_rgb``), so a
file may define Mitsuba plugin classes at import. Dask workers import the same files
(:class:`~.cluster.WorkerSetup`), so every file must be on a file system the workers see.
"""
from __future__ import annotations

import hashlib
import importlib.util
import os
import sys

#: The command-line option that names an extension file.
OPTION = "--plugin"

_loaded: dict[str, object] = {}


class ExtensionError(ValueError):
    """An extension file that does not exist or fails to import (the message says which)."""


def files_in(argv) -> list[str]:
    """The files named by ``--plugin FILE`` / ``--plugin=FILE`` in ``argv``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    found = []
    for i, token in enumerate(argv):
        if token == OPTION and i + 1 < len(argv):
            found.append(argv[i + 1])
        elif token.startswith(OPTION + "="):
            found.append(token.split("=", 1)[1])
    return found


def load(path: str):
    """Import the extension file at ``path`` once (by its absolute path); its module."""
    path = os.path.abspath(path)
    if path in _loaded:
        return _loaded[path]
    if not os.path.isfile(path):
        raise ExtensionError(f"{OPTION} '{path}' does not exist")
    name = "vr_extension_" + hashlib.sha1(path.encode()).hexdigest()[:10]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as e:  # noqa: BLE001  (any error of a user's file, reported as such)
        del sys.modules[name]
        raise ExtensionError(f"{OPTION} '{path}' failed to import: {type(e).__name__}: "
                             f"{str(e).strip().splitlines()[0] if str(e).strip() else ''}") from e
    _loaded[path] = module
    return module


def load_all(paths) -> list:
    return [load(p) for p in paths]


def loaded() -> tuple[str, ...]:
    """The extension files imported so far (absolute paths, in order)."""
    return tuple(_loaded)
