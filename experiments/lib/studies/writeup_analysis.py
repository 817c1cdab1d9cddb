"""The writeup study's numbers and conclusions: a pure function of measured numbers.

:func:`analyse` takes :class:`Measured` (per compared pair: each side's per-repeat MSE
against the reference, its own expected MSE not yet subtracted, the RMSE of the image
shown, and the bias or convergence check of the images) and returns a :class:`Result`
with every ratio, interval, verdict, table row and sentence of the report. No store, no
files, no rendering: the tests feed it synthetic numbers (``tests/test_writeup.py``).

The headline ratio is ``B/A`` (RMSE of B over RMSE of A at equal spp): above 1, A has
less error. Every expected MSE has the reference's own subtracted
(:func:`~..stats.excess_interval`): one below the reference's noise is an upper bound,
and the ratio of a pair with such a side cannot be told.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .. import stats
from .conclusion import MAX_SENTENCES, Comparison, untold

NAME = "writeup"


# ------------------------------------------------------------------ what was measured

@dataclass(frozen=True)
class Side:
    """One method of a pair at the pair's count, over the repeats."""
    method: str
    mse: tuple                  # per repeat, against the reference (its floor included)
    rmse_shown: float           # RMSE of the first run's image (the one shown)
    deterministic: bool = False


@dataclass(frozen=True)
class PairMeasured:
    """A at ``spp`` against B at ``spp``; ``check``: :func:`~..metrics.bias_check` of A
    against B (random A), or :func:`~..metrics.deterministic_check` of A's ladder (plain
    Halton)."""
    a: Side
    b: Side
    spp: int
    check: dict


@dataclass(frozen=True)
class FullMeasured:
    """A --full bias check of A against B at ``spp`` (one run each)."""
    a: str
    b: str
    spp: int
    passes: int
    seconds_a: float
    seconds_b: float
    deterministic: bool
    check: dict


@dataclass(frozen=True)
class Measured:
    pairs: list                 # [PairMeasured]
    full: list                  # [FullMeasured]
    floor: float                # the reference's own expected MSE
    repeats: int
    images: object = None       # what the report shows (not used by the analysis)
    reference: dict = field(default_factory=dict)


# ------------------------------------------------------------------ the result

@dataclass(frozen=True)
class PairResult:
    a: str
    b: str
    spp: int
    mse_a: stats.Estimate       # expected MSE, the reference's own subtracted
    mse_b: stats.Estimate
    rmse_a: float               # sqrt of the expected MSE (of its upper bound for a bound)
    rmse_b: float
    variance_ratio: stats.Estimate    # MSE_B / MSE_A
    rmse_ratio: stats.Estimate        # RMSE_B / RMSE_A (> 1: A has less error)
    comparison: Comparison          # the conclusion's row (ratio RMSE_B / RMSE_A)
    shown_ratio: float          # RMSE_B / RMSE_A of the images shown (one run)
    rmse_shown_a: float
    rmse_shown_b: float

    @property
    def verdict(self) -> str:
        return self.comparison.sentence()

    def bounds(self) -> list[str]:
        """Which RMSEs are only upper bounds (below the reference's noise)."""
        return [f"RMSE {k}" for k, e in (("B", self.mse_b), ("A", self.mse_a)) if e.bound]


@dataclass(frozen=True)
class Result:
    pairs: list                 # [PairResult]
    conclusion: list            # [conclusion.Comparison], one per pair
    sentences: list             # at most three, made from the conclusion's rows
    bias_rows: list             # rows of the short bias table (random pairs)
    deterministic_rows: list    # rows of the short convergence check (plain Halton)
    full_rows: list
    full_deterministic_rows: list
    full_pass_fractions: dict   # (a, b) -> share of pixel values passing the z-test


def _sqrt(x: float) -> float:
    return math.sqrt(x) if x > 0 else float("nan")


def bias_row(label: str, check: dict) -> list:
    ci = ", ".join(f"{d:+.2e} ± {h:.1e}" for d, h in zip(check["mean_diff"],
                                                       check["ci_half_width"]))
    inside = "yes" if all(check["ci_contains_zero"]) else "no"
    per_channel = " / ".join(f"{f:.2%}" for f in check["pass_fraction_per_channel"])
    return [label, ci, inside, f"{check['pass_fraction']:.2%}", per_channel]


def deterministic_rows(name: str, check: dict) -> list:
    return [[name, s, f"{e:.3e}", ", ".join(f"{d:+.2e}" for d in diff),
             f"{check['slope']:.2f}", "yes" if check["converges"] else "no"]
            for s, e, diff in zip(check["spp"], check["mse"], check["mean_diff"])]


def compare(p: PairMeasured, floor: float) -> PairResult:
    """One pair: expected MSEs with the reference's own subtracted, their ratio B/A with
    its interval (it cannot be told when either is a bound), and the verdict."""
    a, b = p.a.method, p.b.method
    excess = {side.method: tuple(v - floor for v in side.mse) for side in (p.a, p.b)}
    expected = {side.method: stats.excess_interval(side.mse, floor) for side in (p.a, p.b)}
    if expected[a].bound or expected[b].bound:
        var_ratio = untold(min(len(p.a.mse), len(p.b.mse)))
    else:
        var_ratio = stats.ratio_interval([excess[b]], [excess[a]])
    rmse_ratio = stats.Estimate(*(_sqrt(x) for x in (var_ratio.value, var_ratio.lo,
                                                     var_ratio.hi)), var_ratio.n)
    rmse = {n: math.sqrt(max(e.value, 0)) for n, e in expected.items()}
    row = Comparison(a, b, f"RMSE B/A at {p.spp} spp", rmse_ratio, "accurate",
                       context=f"After {p.spp} spp")
    return PairResult(a, b, p.spp, expected[a], expected[b], rmse[a], rmse[b], var_ratio,
                      rmse_ratio, row, p.b.rmse_shown / p.a.rmse_shown,
                      p.a.rmse_shown, p.b.rmse_shown)


def analyse(measured: Measured, settings=None) -> Result:
    """Pure: the tables, ratios and verdicts of ``measured``."""
    pairs = [compare(p, measured.floor) for p in measured.pairs]
    bias, det = [], []
    for p in measured.pairs:
        if p.a.deterministic:
            det += deterministic_rows(p.a.method, p.check)
        else:
            bias.append(bias_row(f"{p.a.method} − {p.b.method} ({p.spp} spp)", p.check))
    full, full_det, passing = [], [], {}
    for f in measured.full:
        if f.deterministic:
            full_det += deterministic_rows(f.a, f.check)
            continue
        full.append(bias_row(f"{f.a} − {f.b}", f.check)
                    + [f.passes, f"{f.seconds_a:.1f}", f"{f.seconds_b:.1f}"])
        passing[(f.a, f.b)] = f.check["pass_fraction"]
    table = [p.comparison for p in pairs]
    return Result(pairs, table, [c.sentence() for c in table][:MAX_SENTENCES], bias, det,
                  full, full_det, passing)
