"""The mutants of adaptive sampling (its allocation, its pilot, its predicted gain, its counts
in the studies), a part of :data:`tools.mutant_list.MUTANTS`: realistic bugs, one each (see
that module)."""
from tools.mutant import Mutant

ADAPTIVE = [
    Mutant("adaptive-by-variance", "integrators/adaptive.py",
           "        return (self._counts(dr.sqrt(own), budget, size),",
           "        return (self._counts(own, budget, size),",
           "samples allocated in proportion to the relative variance instead of the relative "
           "standard deviation (the relMSE-optimal rule): unbiased, but the error is larger",
           ("tests/test_adaptive.py::test_the_allocation_is_proportional_to_the_relative_deviation",)),
    Mutant("adaptive-pilot-double-counted", "integrators/adaptive.py",
           "    return weight * (pilot / n_pilot) + (1.0 - weight) * (final / n_final)",
           "    return weight * (2.0 * pilot / n_pilot) + (1.0 - weight) * (final / n_final)",
           "the pilot's samples counted twice when the passes are combined: the image too "
           "bright by the pilot's weight",
           ("tests/test_adaptive.py::test_adaptive_agrees_with_path_per_block",)),
    Mutant("adaptive-own-pilot", "integrators/adaptive.py",
           "    weight = n_pilot / (n_pilot + planned)",
           "    weight = n_pilot / (n_pilot + n_final)",
           "the pilot weighted by the pixel's own count, which reads its own pilot: each "
           "pixel's mean over all its samples (optional stopping: a pixel whose pilot "
           "missed a rare bright path keeps its low mean)",
           ("tests/test_adaptive.py::test_a_heavy_pixel_stays_unbiased",)),
    Mutant("allocation-map-without-pilot", "integrators/adaptive.py",
           "        self.last_counts = counts + pilot",
           "        self.last_counts = counts",
           "the report's map of where adaptive sampling put its samples leaves out the "
           "pilot's (every pixel's count a quarter short)",
           ("tests/test_adaptive.py",)),
    Mutant("adaptive-zero-samples", "integrators/adaptive.py",
           "        return dr.opaque(mi.UInt32, least) + mi.UInt32(dr.floor(share *",
           "        return mi.UInt32(dr.floor(share *",
           "no floor: a pixel whose pilot saw no variance rounds to 0 samples in the final "
           "pass, its mean 0/0",
           ("tests/test_adaptive.py::test_no_pixel_gets_no_samples_and_the_image_is_finite",
            "tests/test_adaptive.py")),
    Mutant("oracle-unsquared", "experiments/lib/studies/suite/errors.py",
           "    return float(np.mean(v)) / (root * root) if root > 0 else math.nan",
           "    return float(np.mean(v)) / root if root > 0 else math.nan",
           "the adaptive ceiling divides by the mean relative deviation, not its square: "
           "the ceiling then follows the image's brightness",
           ("tests/test_suite_errors.py::test_the_adaptive_ceiling_is_the_oracle_allocations_gain",)),
    Mutant("adaptive-gain-ignored", "integrators/adaptive.py",
           "        self.last_allocated = self.last_gain >= self.min_gain\n",
           "        self.last_allocated = True\n",
           "samples moved between pixels where the pilot predicts too little gain for the "
           "move (small_light and cbox at their equal-time counts: a pilot of 11 samples per "
           "pixel, 0.89 to 0.99 of bsdf+nee)",
           ("tests/test_adaptive.py::test_where_the_pilot_predicts_little_gain_every_pixel_gets_the_same_count",)),
    Mutant("adaptive-gain-in-sample", "integrators/adaptive.py",
           "            judge = v[1 - h]\n",
           "            judge = v[h]\n",
           "the predicted gain judged by the samples it allocated by: a pilot's noise looks "
           "like differences worth allocating to (pure noise read 5.3, the stability study's "
           "small lights without NEE allocated and lost)",
           ("tests/test_adaptive.py::test_a_pilots_noise_predicts_no_gain",)),
    Mutant("adaptive-uniform-pilot-dropped-from-count", "integrators/adaptive.py",
           "        return (total + rest * float(final)) / float(pilot + final)\n",
           "        return (total + rest * float(final)) / float(final)\n",
           "where every pixel gets the same count, the pilot's sums pooled with the final "
           "render's but divided by the final render's samples alone: the image too bright",
           ("tests/test_adaptive.py::test_where_the_pilot_predicts_little_gain_every_pixel_gets_the_same_count",)),
    Mutant("adaptive-count-rounded", "experiments/lib/engine_pilots.py",
           "    return counts.equal_time_spp(seconds, piloted, False, budget.max_spp)\n",
           "    return counts.equal_time_spp(seconds, piloted, budget.power_of_two, budget.max_spp)\n",
           "an adaptive method's equal-time count rounded to a power of two as a plain "
           "method's: it rendered half its twin's count on four of nine scenes",
           ("tests/test_learner_counts.py::test_an_adaptive_methods_count_is_exact_and_from_a_pilot",)),
    Mutant("adaptive-count-unpiloted", "experiments/lib/engine.py",
           "        if slot.method.adaptive:\n",
           "        if False:\n",
           "an adaptive method counted from its short renders' cost, whose fixed work per job "
           "spread over their few samples gives too few",
           ("tests/test_learner_counts.py::test_an_adaptive_methods_count_is_exact_and_from_a_pilot",)),
    Mutant("adaptive-over-baseline", "experiments/lib/studies/suite/analysis.py",
           '    adapted = {m: compare(m, twin) for m in cells if (twin := _twin(m, "unadapted")) in cells}',
           '    adapted = {m: compare(m, base) for m in cells if (twin := _twin(m, "unadapted")) in cells}',
           "the adaptive method's finding compares it with the baseline (path), not with its "
           "twin that samples every pixel alike: what adaptive sampling gains is then mixed "
           "with what its strategy gains",
           ("tests/test_suite.py::test_an_adaptive_method_is_compared_with_its_twin_on_every_scene",)),
    Mutant("adaptive-warmed-as-plain", "experiments/lib/execute.py",
           "    if method.adaptive:\n        from integrators import adaptive\n",
           "    if False:\n        from integrators import adaptive\n",
           "an adaptive method warmed up at a plain method's count (4 spp): its pilot takes "
           "them all, the warm-up render fails and so does the cell",
           ("tests/test_adaptive.py::test_the_suite_measures_an_adaptive_cell",)),
    Mutant("ceiling-time-uniform-cost", "benchmarks/adaptive.py",
           '            "time": samples * float(np.mean(cost) / (np.sum(r * cost) / np.sum(r))),\n',
           '            "time": samples * float(np.mean(cost) / np.mean(cost)),\n',
           "the equal-time ceiling costs the allocation's samples as a uniform render's: "
           "where the pixels that need samples are dear it reads as the equal-samples "
           "ceiling (environment 1.61 for 1.25)",
           ("tests/test_bench_adaptive.py::test_the_ceilings_of_known_fields",)),
    Mutant("ceiling-plain-only", "experiments/lib/studies/suite/analysis.py",
           'CEILING_METHODS = (TIMED_PAIR[0], "guided+nee")\n',
           'CEILING_METHODS = (TIMED_PAIR[0],)\n',
           "the adaptive ceiling read from bsdf+nee alone: the guiding scenes, which do not "
           "render it, give none, and guided+nee+adaptive's refusal has no number",
           ("tests/test_adaptive.py::test_a_guiding_scene_gives_the_ceiling_of_its_guide",)),
]
