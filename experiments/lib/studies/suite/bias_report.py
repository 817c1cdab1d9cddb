"""The words and the table of the suite's bias test (:mod:`.bias_test`): the findings
box's sentence, each scene's power sentence, the per-cell table."""
from __future__ import annotations

import math
from collections import Counter

from ... import bias_image, prose
from . import analysis, bias_renders, bias_test
from .declare import NAME


def names(methods, limit: int = 4) -> str:
    """'a', 'a and b', 'a, b and c', at most ``limit`` named ('... and 2 more')."""
    methods = list(methods)
    if len(methods) > limit:
        return ", ".join(methods[:limit]) + f" and {len(methods) - limit} more"
    return prose.and_join(methods) if methods else "none"


UNTESTABLE = {"deterministic": "a deterministic sampler (no independent renders)",
              "user_reference": "a user's EXR reference (no chunks, its variance unknown)",
              "too_few_renders": "too few renders (fewer than 2 per budget)",
              "unequal_counts": "renders of unequal sample counts within a budget",
              "heavy_tails": "heavy tails (one sample rules the variance of many "
                             "blocks, and the image sum's variance is unsure: one pixel "
                             "of one render holds more than "
                             f"{bias_image.MAX_TERM_SHARE:.0%} of it, or the renders' own "
                             f"variances have fewer than {bias_image.MIN_DOF} degrees of "
                             "freedom: the test's size is void)",
              "no_power": "no power (its image sum's variance known, but not even a bias of "
                          "100% would be found at the run's budget)",
              "calibration": "its calibration failed (the method that renders the reference "
                             "did not pass its own test on this scene)",
              "unreached_lobe": "an unreached lobe (flagged, but its strategy draws the core "
                                "of the scene's narrowest lobe so rarely that all its samples "
                                f"pass through it fewer than {bias_test.REACH_MIN:g} times: a "
                                "correct estimator misses that light, and nothing in its "
                                "samples tells that from a bias)"}
BIAS_FINDING = (
    "Bias test (every cell against its scene's reference, per {{ block }}x{{ block }} block "
    "and channel and pooled over the image, Welch, {{ level | pct }} family-wise over the run): "
    "{% if flagged %}BIASED: {{ flagged | join('; ') }}{% else %}no method flagged{% endif %}"
    "{% if image %}; {{ image }} cells with heavy-tailed blocks tested by their image sums "
    "alone{% endif %}"
    "{% if retested %}; {{ retested | length }} flagged cells tested again on "
    "{{ more }} x the repeats of fresh renders: {{ retested | join('; ') }}{% endif %}"
    "{% if again %}; {{ again }} cells whose tails voided the test rendered again "
    "({{ more }} x the repeats at their equal-time count) and tested with those renders, "
    "{{ cleared }} of them testable then{% endif %}"
    "{% if untestable %}; untestable: {{ untestable }} (each cell in "
    "{{ table }}){% endif %}"
    "{% if powers %}; smallest bias detected 90% of the time: {{ powers | join(', ') }}"
    "{% endif %}.")
POWER = ("Its bias test detects a uniform bias of {{ power }} about 90% of the time "
         "(measured on {{ method }}{% if calibration %}, the reference's own method: the "
         "test's negative control{% endif %}{% if indicative %}; indicative only: "
         "{{ method }}'s renders are heavy-tailed here{% endif %}){% if flagged %}; "
         "flagged as biased: {{ flagged | join(', ') }}{% endif %}.")


def pct2(x: float) -> str:
    return f"{x:.2%}" if math.isfinite(x) else "no bias up to 100%"


def bias_words(r: analysis.SceneResult) -> str:
    """The scene's bias-test sentence ('' where nothing was tested)."""
    if r.power is None:
        return ""
    flagged = [m for m, c in r.cells.items() if c.biased]
    return prose.say(POWER, power=pct2(r.power), method=r.power_method,
                     calibration=r.power_method == r.calibration, flagged=flagged,
                     indicative=power_indicative(r))


def power_indicative(r: analysis.SceneResult) -> bool:
    """Whether the scene's power comes from a cell untestable for heavy tails (its variance
    estimates fall short: the stated power is optimistic)."""
    cell = r.cells.get(r.power_method)
    b = cell.block_bias if cell is not None else None
    return b is not None and b.status == "untestable" and b.reason == "heavy_tails"


def difference(b: bias_test.CellBias) -> str:
    """What a flagged cell's test saw: its pooled difference and flagged blocks, or its
    image sum's difference."""
    worst = max(b.delta, key=abs)
    if b.scope == "image":
        return f"image sum {worst:+.2%}"
    return f"pooled difference {worst:+.2%}, {b.flagged_blocks} blocks"


def bias_finding(results: list) -> str:
    """The findings box's bias-test sentence ('' where no cell was tested)."""
    tested = [(r.name, m, c.block_bias) for r in results for m, c in r.cells.items()
              if c.block_bias is not None]
    if not tested:
        return ""
    flagged = [f"{m} on {n} ({difference(b)})" for n, m, b in tested if b.status == "biased"]
    image = sum(b.scope == "image" and b.status != "untestable" for _, _, b in tested)
    reasons = Counter(b.reason for _, _, b in tested if b.status == "untestable")
    untestable = (f"{sum(reasons.values())} of {len(tested)} cells: " + "; ".join(
        f"{UNTESTABLE[reason]}: {count}" for reason, count in reasons.most_common())
        if reasons else "")
    powers = [f"{r.name} {pct2(r.power)}" + (" (indicative only: heavy tails)"
                                             if power_indicative(r) else "")
              for r in results if r.power is not None]
    again = [b for _, _, b in tested if b.extra and not b.retest]
    retested = [f"{m} on {n} {b.retest} (p {b.retest_p:.2g})" for n, m, b in tested
                if b.retest]
    return prose.say(BIAS_FINDING, block=tested[0][2].block, level=bias_test.LEVEL,
                     flagged=flagged, image=image, untestable=untestable, powers=powers,
                     table=BIAS_TABLE, again=len(again), more=bias_renders.MORE,
                     cleared=sum(b.status != "untestable" for b in again),
                     retested=retested)


#: The bias test's table of every cell (under the output folder), which the findings name.
BIAS_TABLE = f"{NAME}/bias_test.csv"
BLOCK_HEADER = ["scene", "method", "biased", "why untestable", "tested", "variance",
                "detectable bias", "pooled difference", "smallest block p", "block level",
                "pooled p", "pooled level", "flagged blocks", "ruled by one sample",
                "image variance in one term", "degrees of freedom of the renders' own",
                "renders again", "flag tested again"]
SCOPES = {"blocks": "blocks and pooled", "image": "image sum"}
#: The caption of :data:`BIAS_TABLE` in the report.
TABLE_CAPTION = (
    f"Bias test of every cell: its renders at both budgets against the reference's "
    f"chunks, Welch's t per block and channel and a pooled test per channel, "
    f"levels {bias_test.LEVEL:.0%} family-wise over the run (Sidak); variance "
    f"from the pixels (independent sampler, box filter) or the renders, and for the "
    f"image sum from each render's own samples where they state it (moments); "
    f"'detectable bias': the smallest uniform bias found about 90% of the time; "
    f"'ruled by one sample': the share of blocks whose variance one pixel of one "
    f"render holds the most of (above {bias_test.TAILS_SHARE:.0%}: heavy tails, "
    f"the cell tested by its image sum alone, the 'image sum' of 'tested'); "
    f"'image variance in one term': the largest share of the image sum's variance "
    f"that one pixel of one render holds, where it is read from their spread (above "
    f"{bias_image.MAX_TERM_SHARE:.0%}: untestable); 'degrees of freedom of the renders' "
    f"own': how sure the image sum's variance read from each render's own samples is "
    f"(Welch-Satterthwaite, from their fourth moments; under {bias_image.MIN_DOF}: "
    f"untestable); 'renders again': where heavy tails voided the first test, the renders "
    f"at the cell's equal-time count added before it was tested again "
    f"({bias_renders.MORE} times the run's repeats, in no comparison), and where it "
    f"flagged the cell, the fresh renders that tested the flag alone; 'flag tested "
    f"again': whether they flagged it too (it stays biased), did not (not biased) or "
    f"could not tell (void: the flag stands), with their smallest p")


def number(x: float) -> str:
    return "-" if math.isnan(x) else f"{x:.2g}"


def share(x: float) -> str:
    return "-" if math.isnan(x) else f"{x:.1%}"


def block_bias_rows(results: dict) -> list[list]:
    """The bias test of every tested cell."""
    rows = []
    for name, r in results.items():
        for m, c in r.cells.items():
            b = c.block_bias
            if b is None:
                continue
            finite = b.status != "untestable" or b.reason in ("heavy_tails", "no_power")
            rows.append([name, m, {True: "YES", False: "no"}.get(b.biased, "untestable"),
                         b.reason, SCOPES[b.scope], b.variance,
                         pct2(b.detectable) if finite else "-",
                         (f"{max(b.delta, key=abs):+.3%}" if b.delta else "-"),
                         number(b.p_blocks if finite else math.nan), number(b.alpha_blocks),
                         number(b.p_pooled if finite else math.nan), number(b.alpha_pooled),
                         b.flagged_blocks, share(b.tail_share), share(b.term_share),
                         "-" if math.isnan(b.own_dof) else f"{b.own_dof:.0f}", b.extra,
                         f"{b.retest} (p {number(b.retest_p)})" if b.retest else "-"])
    return rows
