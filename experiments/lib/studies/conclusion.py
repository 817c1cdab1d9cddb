"""A study's conclusion as a short table a reader can scan, and the sentences beneath it.

Each row is a :class:`Comparison`: method A against method B by a ratio whose value above
1 means A is better (an efficiency A/B, or an error B/A), its interval, the verdict the
interval allows, and, where the study has a ladder of sample counts, the counts at which
the order of A and B changes. The sentences under the table are made from the same rows
(:meth:`Comparison.sentence`), so the prose and the table share one source of numbers.
Pure: no files, no rendering.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .. import stats

#: At most this many sentences beneath a conclusion table, and words per paragraph.
MAX_SENTENCES = 3
MAX_WORDS = 80
HEADER = ["A vs B", "ratio (> 1: A is better)", "ratio", "ratio_lo", "ratio_hi", "verdict",
          "order changes at"]
#: The column naming a row's errors that are only upper bounds (below the reference's own
#: noise: value = _hi, _lo = 0, never NaN); their ratios read n/a (:func:`ratio_cells`).
BOUNDS = "upper bounds (below the reference's noise)"
#: A ratio that cannot be told: an error is below the reference's own noise.
UNTOLD = "cannot be told: an error is below the reference's own noise"


def untold(n: int) -> stats.Estimate:
    """The ratio of a comparison in which one error is only an upper bound."""
    return stats.Estimate(float("nan"), float("nan"), float("nan"), n)


def sign(ratio: stats.Estimate) -> int:
    """+1 when the interval says A is better (above 1), -1 when B is, 0 when it cannot."""
    if not ratio.excludes(1.0):
        return 0
    return 1 if ratio.value > 1 else -1


def order_changes(counts, ratios) -> tuple:
    """The counts at which the interval-decided order of A and B changes along a ladder,
    with the method ahead from there: ``((count, +1 or -1), ...)``; counts where the
    interval decides nothing keep the order decided before them."""
    changes, last = [], 0
    for count, ratio in zip(counts, ratios):
        s = sign(ratio)
        if s != 0 and last != 0 and s != last:
            changes.append((count, s))
        if s != 0:
            last = s
    return tuple(changes)


@dataclass(frozen=True)
class Comparison:
    a: str
    b: str
    measure: str                  # what the ratio is, e.g. "efficiency A/B after 256 spp"
    ratio: stats.Estimate         # > 1: A is better
    quantity: str = "efficient"   # the verdict's adjective ("more efficient")
    context: str = ""             # leads the sentence, e.g. "After 20 spp"
    changes: tuple | None = None  # order_changes along a ladder; None: no ladder

    @property
    def told(self) -> bool:
        return math.isfinite(self.ratio.value)

    @property
    def better(self) -> str | None:
        """The method the interval says is better, or None."""
        return {1: self.a, -1: self.b}.get(sign(self.ratio))

    def verdict(self) -> str:
        """The table's verdict: which is better, or why that cannot be said."""
        if not self.told:
            return UNTOLD
        if self.better is None:
            return "not distinguishable" + ("" if self.ratio.known else " (one run)")
        return f"{self.better} is more {self.quantity}"

    def changes_text(self) -> str:
        if self.changes is None:
            return "(no ladder)"
        if not self.changes:
            return "none"
        return "; ".join(f"{count} spp ({self.a if s > 0 else self.b} ahead from there)"
                         for count, s in self.changes)

    def cells(self) -> list:
        return [f"{self.a} vs {self.b}", self.measure, *ratio_cells(self.ratio),
                self.verdict(), self.changes_text()]

    def sentence(self) -> str:
        """The row as one sentence: the verdict with its ratio and interval, after
        ``context`` (written capitalised) and a colon."""
        if self.told:
            body = stats.verdict(self.a, self.b, self.ratio, self.quantity)
        else:
            body = f"{self.a} against {self.b} {UNTOLD} (a better reference is needed)"
        if self.changes:
            body += f" (the order changes along the ladder at {self.changes_text()})"
        return f"{self.context}: {body}." if self.context else f"{body}."


def ratio_cells(ratio: stats.Estimate) -> list[str]:
    """``[value, lo, hi]`` as table cells; "n/a" where a ratio cannot be told (or has no
    interval)."""
    return [stats.g(x) if math.isfinite(x) else "n/a" for x in (ratio.value, ratio.lo,
                                                                 ratio.hi)]


def rows(comparisons) -> list[list]:
    return [c.cells() for c in comparisons]


def words(text: str) -> int:
    return len(text.split())


def long_paragraphs(blocks, limit: int = MAX_WORDS) -> list[str]:
    """Paragraphs of a section's ``blocks`` longer than ``limit`` words: every text block's
    paragraphs (split at blank lines) and every caption."""
    found = []
    for block in blocks:
        texts = block["text"].split("\n\n") if block["kind"] == "text" else \
            [block.get("caption", "")]
        found += [t for t in texts if words(t) > limit]
    return found
