"""The report layer's words: sentences made from analysis data with jinja2 templates.

Analysis returns numbers and verdicts as data; the report modules turn them into words
with :func:`say` over a template (a module-level string constant beside the report code
that uses it). Undefined names are errors, never empty text (``StrictUndefined``); the
filters the reports need are defined here once: ``g`` (a number in 3 significant digits,
:func:`.stats.g`), ``pct`` (a share as a percentage), ``join`` with a final "and"
(``and_join``).
"""
from __future__ import annotations

from functools import lru_cache

import jinja2

from . import stats


def and_join(items) -> str:
    """'a', 'a and b', 'a, b and c'."""
    items = [str(i) for i in items]
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1] \
        if items else ""


def _pct(x: float, digits: int = 0) -> str:
    return f"{100 * float(x):.{digits}f}%"


@lru_cache(maxsize=None)
def _environment() -> jinja2.Environment:
    env = jinja2.Environment(undefined=jinja2.StrictUndefined, trim_blocks=True,
                             lstrip_blocks=True, keep_trailing_newline=False, autoescape=False)
    env.filters.update(g=stats.g, pct=_pct, and_join=and_join)
    return env


@lru_cache(maxsize=256)
def _template(text: str) -> jinja2.Template:
    return _environment().from_string(text)


def say(template: str, **values) -> str:
    """``template`` filled with ``values``; runs of whitespace (the template's line breaks
    and indentation) become single spaces, so a template may be wrapped freely."""
    return " ".join(_template(template).render(**values).split())
