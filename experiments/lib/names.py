"""How errors are named in one line (the reports' failure tables, the engine's failed cells)."""
from __future__ import annotations


def one_line(error: BaseException) -> str:
    """The innermost cause of an error, first line (mi.render wraps a plugin's error)."""
    while error.__cause__ is not None:
        error = error.__cause__
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0] if text else ''}"
