"""The sampling lab's mass and albedo checks in the report: a table per panel and sentences.

The numbers and verdicts come from :func:`experiments.lib.studies.lab.mass.analyse`; the words
from the templates here (:func:`experiments.lib.prose.say`). A panel fails when its
chi-square test rejects its density or either check fails.
"""
from __future__ import annotations

from experiments.lib import prose, report
from experiments.lib.studies.lab import mass

NAME = "lab"

HEADER = ["bsdf", "incidence_deg", "strategy", "chi-square p", "mass / share drawn",
          "mass interval", "mass check", "E[w] / albedo", "E[w] interval", "albedo check",
          "panel"]

ALL_PASS = """Every one of the {{ panels }} panels passes the mass and albedo checks at 1%
(Sidak over {{ tests }} checks, z = {{ z | g }}; tolerance {{ tol | pct }}): the density
each strategy weights by integrates to the share of directions it draws, and its mean
weight is the BSDF's albedo."""
SOME_FAIL = """{{ failed }} of {{ panels }} panels fail the mass or albedo check at 1%
(Sidak over {{ tests }} checks, z = {{ z | g }}; beyond a tolerance of {{ tol | pct }}):
{{ shown }}{{ more }}; a density off by a constant factor makes every pixel too dark or too
bright, which the chi-square test cannot see."""
UNDECIDED = """{{ count }} of {{ panels }} panels cannot decide one check ({{ reasons }}):
{{ per }}; more samples per panel (--samples) narrow them."""
DECIDED = """Every check decides: no interval is wider than {{ wide | pct }} and no weight's
tail is too heavy for its normal approximation."""
REASONS = {"wide": "an interval wider than {wide}", "heavy tails":
           "weights too heavy-tailed for a normal interval", "nothing to compare":
           "nothing drawn or a zero albedo"}


def _where(row) -> str:
    return f"{row.strategy} on {row.bsdf} at {row.incidence_deg:g} deg"


def _failure(row) -> str:
    parts = [f"{name} {c.ratio:.3g} [{c.low:.3g}, {c.high:.3g}]"
             for name, c in (("mass/share", row.mass), ("E[w]/albedo", row.albedo))
             if c.verdict == mass.FAIL]
    return f"{_where(row)} ({'; '.join(parts)})"


def sentences(found: mass.Findings) -> list[str]:
    """At most two sentences from the checks' findings."""
    common = {"panels": len(found.rows), "tests": found.tests, "z": found.z,
              "tol": mass.TOLERANCE}
    if found.failed:
        out = [prose.say(SOME_FAIL, failed=len(found.failed), shown="; ".join(
            _failure(r) for r in found.failed[:2]), more=(
                f" and {len(found.failed) - 2} more (table)" if len(found.failed) > 2 else ""),
            **common)]
    else:
        out = [prose.say(ALL_PASS, **common)]
    if found.undecided:
        reasons = dict.fromkeys(c.reason for r in found.undecided for c in (r.mass, r.albedo)
                                if c.verdict == mass.UNDECIDED)
        per = [f"{s} in {u}" for s, _, _, u in found.per_strategy if u]
        out.append(prose.say(UNDECIDED, count=len(found.undecided), panels=len(found.rows),
                             reasons=prose.and_join(REASONS[r].format(
                                 wide=f"±{100 * mass.WIDE:g}%") for r in reasons),
                             per=prose.and_join(per)))
    else:
        out.append(prose.say(DECIDED, wide=mass.WIDE))
    return out


def _verdict(c: mass.Check) -> str:
    return c.verdict if c.verdict != mass.UNDECIDED else f"{c.verdict} ({c.reason})"


def panel_verdict(row, p_value: float, alpha: float) -> str:
    """fail (chi-square or either check), cannot decide, or pass."""
    if row.failed or not p_value >= alpha:
        return mass.FAIL
    return mass.UNDECIDED if row.undecided else mass.PASS


#: The verdict column of the warps' conclusion table (:func:`strategy_verdict`).
VERDICT_HEADER = "verdict (chi-square, mass, albedo)"


def strategy_verdict(strategy: str, rejected: int, found: mass.Findings) -> str:
    """One strategy's verdict over all its panels and all three checks: ``fail`` with the
    count of panels that fail each (``rejected``: its chi-square rejections), else
    ``cannot decide`` with the count of undecided panels, else ``pass``."""
    mine = [r for r in found.rows if r.strategy == strategy]
    masses = sum(r.mass.verdict == mass.FAIL for r in mine)
    albedos = sum(r.albedo.verdict == mass.FAIL for r in mine)
    if rejected or masses or albedos:
        return (f"{mass.FAIL}: chi-square {rejected}, mass {masses}, albedo {albedos} of "
                f"{len(mine)} panels")
    undecided = sum(r.undecided for r in mine)
    return (f"{mass.UNDECIDED} ({undecided} of {len(mine)} panels)" if undecided
            else mass.PASS)


def report_checks(out: str, found: mass.Findings, p_values: list, alpha: float) -> list:
    """The table (one row per panel, in ``found``'s order; ``p_values`` the panels'
    chi-square p-values, ``alpha`` their Sidak level) and the sentences."""
    rows = [[r.bsdf, f"{r.incidence_deg:g}", r.strategy, f"{p:.3g}",
             f"{r.mass.ratio:.4f}", f"[{r.mass.low:.4f}, {r.mass.high:.4f}]", _verdict(r.mass),
             f"{r.albedo.ratio:.4f}", f"[{r.albedo.low:.4f}, {r.albedo.high:.4f}]",
             _verdict(r.albedo), panel_verdict(r, p, alpha)]
            for r, p in zip(found.rows, p_values)]
    return [report.write_table(
        out, f"{NAME}/mass_albedo", HEADER, rows,
        f"What the chi-square cannot see, per panel: the strategy's density integrated over "
        f"the sphere (trapezoid quadrature, bounded by halving its points) against the share "
        f"of directions drawn, and the mean weight E[f·cos/pdf] against the albedo (the "
        f"quadrature of f·cos); intervals ratio × (1 ± (z·se + quadrature bound)), z = "
        f"{found.z:.3g} (1% Sidak over {found.tests} checks); a check fails outside "
        f"1 ± {mass.TOLERANCE:g} and cannot decide when wider than ±{mass.WIDE:g} "
        f"or when the weights are too heavy-tailed (Cochran: n < "
        f"{mass.SKEW_SAMPLES:g} skewness²); a panel fails on either check or its "
        f"chi-square", collapsed=True),
        report.text("\n\n".join(sentences(found)))]
