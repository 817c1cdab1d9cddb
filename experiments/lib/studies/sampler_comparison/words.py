"""The sampler study's sentences: words made from its analysis data (the report layer).

The analyses (:mod:`.sampler_comparison.analysis`, :mod:`.sampler_comparison.screen_analysis`)
return numbers and verdicts; this module makes the at most three sentences per depth under
each conclusion table from them alone: :func:`sentences` (the efficiency pass: the winner,
the bundled samplers against the best native one, where an order changes along the ladder),
:func:`screen_sentences` (the screen-space pass: mean FLIP along the ladder, the counts with
a bluer error than every native sampler's, MSE efficiency), and :func:`conclusions` /
:func:`screen_conclusions` for every depth. The longer sentences are :func:`.prose.say`
templates.
"""
from __future__ import annotations

from experiments.lib import prose
from experiments.lib.studies.sampler_comparison.analysis import (
    BEST, BUNDLED, METRIC, METRIC_NAMES, NATIVE, WORDS, Analysis, Comparison, Family,
    order_text, sign)
from experiments.lib.studies.sampler_comparison.screen_analysis import (
    FLIP_WORDS, ScreenAnalysis, ScreenComparison, ScreenRow)

WINNER = """At max_depth {{ depth }} and {{ spp }} spp, {{ a }} is the most efficient sampler
    by {{ metric }}; against the runner-up, {{ runner }}: {{ verdict }}."""
AGAINST_NATIVE = "Against the best native sampler, {{ native }}: {{ verdicts | join('; ') }}."
NO_LASTING_WINNER = """Along the ladder the order changes without a lasting winner in
    {{ n }} comparison(s) (table)."""
NO_CHANGE = """No order between a bundled and a native sampler changes along the
    ladder{{ span }}."""
FLIP_HEAD = """By mean FLIP at max_depth {{ depth }}, against the native sampler lowest at
    {{ top }} spp ({{ best }}): """
BLUER_HEAD = """Error bluer than every native sampler's (low-frequency share, white noise
    {{ '%.3f' | format(white) }}; natives {{ lo | g }}-{{ hi | g }} at {{ top }} spp): """
EFFICIENT_HEAD = """In MSE efficiency against the most efficient native sampler at
    {{ top }} spp ({{ eff }}): """

def _overtake_text(c: Comparison) -> str:
    winner, loser, n = c.overtakes
    last = c.changes[-1][0]
    return (f"{winner} overtakes {loser} at the largest count ({n} spp)" if n == last else
            f"{winner} overtakes {loser} from {n} spp")


def sentences(table_rows: list[Comparison], limit: int = 3) -> list[str]:
    """At most three sentences about one depth, computed from its conclusion table alone:
    the winner, the bundled samplers against the best native one, and where the order
    between a bundled and a native sampler changes along the ladder."""
    out = []
    best = next((c for c in table_rows if c.role == BEST), None)
    bundled = [c for c in table_rows if c.role == BUNDLED]
    same = [c for c in bundled if best is not None and {c.a, c.b} == {best.a, best.b}]
    if best is not None:
        runner = (f"{best.b} (also the best native sampler)"
                  if same and same[0].b == best.b else best.b)
        out.append(prose.say(WINNER, depth=best.depth, spp=best.spp, a=best.a,
                             metric=METRIC_NAMES[METRIC], runner=runner,
                             verdict=best.verdict))
    rest = [c for c in bundled if c not in same]
    if rest:
        out.append(prose.say(AGAINST_NATIVE, native=rest[0].b,
                             verdicts=[c.verdict for c in rest]))
    ladder = [c for c in table_rows if c.role in (BUNDLED, NATIVE)]
    moves = [c for c in ladder if c.overtakes]
    flips = [c for c in ladder if c.onsets]
    if moves:
        more = f" and {len(moves) - 3} more (table)" if len(moves) > 3 else ""
        out.append("Along the ladder, " + "; ".join(map(_overtake_text, moves[:3]))
                   + f"{more}.")
    elif flips:
        out.append(prose.say(NO_LASTING_WINNER, n=len(flips)))
    elif bundled:
        first = bundled[0].changes
        span = f" ({first[0][0]}-{first[-1][0]} spp)" if first else ""
        out.append(prose.say(NO_CHANGE, span=span))
    return out[:limit]



def _along(changes, words: dict) -> str:
    """:func:`order_text` without its '(no change)'."""
    return order_text(changes, words).removesuffix(" (no change)")


def _fit(parts: list[str], head: str, tail: str = ".", limit: int = 80) -> str:
    """``head`` + the parts joined by '; ' + ``tail``, leaving out the last parts (said to
    be in the table) where the sentence would pass ``limit`` words."""
    for n in range(len(parts), 0, -1):
        more = "" if n == len(parts) else "; the others in the table"
        text = head + "; ".join(parts[:n]) + more + tail
        if len(text.split()) <= limit:
            return text
    return head + "see the table" + tail


def screen_sentences(depth: int, comps: list[ScreenComparison], rows: list[ScreenRow],
                     kinds: dict[str, Family], white: float) -> list[str]:
    """At most three sentences about one depth, from its comparisons and rows alone: each
    bundled family's best against the best native sampler in mean FLIP along the ladder;
    the counts at which its error is bluer than every native sampler's; and its MSE
    efficiency against the most efficient native sampler."""
    mine = [c for c in comps if c.depth == depth]
    at = [r for r in rows if r.depth == depth]
    if not mine:
        return []
    top = max(r.requested for r in at)
    last = [r for r in at if r.requested == top]
    natives = [r for r in last if kinds[r.sampler].native]
    if not natives:
        return []
    families = list(dict.fromkeys(c.a for c in mine if kinds[c.a].name != kinds[c.b].name
                                  and kinds[c.b].native))

    def ladder(a, b):
        return [c for c in mine if (c.a, c.b) == (a, b)]

    # the lowest FLIP among the natives that render the count asked for
    best = min([r for r in natives if r.spp == r.requested] or natives,
               key=lambda r: r.flip.value).sampler
    parts = []
    for a in families:
        cs = ladder(a, best)
        changes = [(c.spp[0], c.signs[0], c.flip) for c in cs]
        parts.append(f"{a} {_along(changes, FLIP_WORDS)}, ratio {cs[-1].flip.text()} at "
                     f"{cs[-1].spp[0]} spp")
    out = [_fit(parts, prose.say(FLIP_HEAD, depth=depth, top=top, best=best) + " ")]
    parts = []
    for a in families:
        against = [c for c in mine if c.a == a and kinds[c.b].native]
        counts = sorted({c.requested for c in against})
        bluer = [n for n in counts
                 if all(c.signs[1] > 0 for c in against if c.requested == n)]
        share = next(r.share for r in last if r.sampler == a)
        parts.append((f"{a} at {', '.join(map(str, bluer))} spp" if bluer else
                      f"{a} at no count") + f", share {share.text()} at {top} spp")
    lo, hi = min(r.share.value for r in natives), max(r.share.value for r in natives)
    out.append(_fit(parts, prose.say(BLUER_HEAD, white=white, lo=lo, hi=hi, top=top) + " "))
    known = [r for r in natives if not r.mse.bound and r.mse.value > 0]
    if known:
        # Veach's efficiency 1 / (MSE x time per pixel) of each native label
        eff = max(known, key=lambda r: 1 / (r.mse.value * r.us_per_sample * r.spp)).sampler
        parts = []
        for a in families:
            cs = ladder(a, eff)
            changes = [(c.spp[0], sign(c.efficiency), c.efficiency) for c in cs]
            parts.append(f"{a} {_along(changes, WORDS)}")
        out.append(_fit(parts, prose.say(EFFICIENT_HEAD, top=top, eff=eff) + " "))
    return out[:3]


def conclusions(result: Analysis) -> dict:
    """``{depth: [sentence]}`` of the efficiency pass."""
    depths = sorted({r.depth for r in result.rows})
    return {d: sentences([c for c in result.comparisons if c.depth == d]) for d in depths}


def screen_conclusions(result: ScreenAnalysis) -> dict:
    """``{depth: [sentence]}`` of the screen-space pass."""
    return {d: screen_sentences(d, result.comparisons, result.rows, result.kinds, result.white)
            for d in sorted({r.depth for r in result.rows})}
