"""The mutants of the suite's bias test (its blocks, its image test, the round of more
renders), a part of :data:`tools.mutant_list.MUTANTS`: realistic bugs, one each (see that
module)."""
from tools.mutant import Mutant

BIAS = [
    Mutant("welch-one-side", "experiments/lib/bias.py",
           "    se2 = np.maximum(va + vb, 1e-300)\n",
           "    se2 = np.maximum(va, 1e-300)\n",
           "Welch's variance of the difference without the reference's share (a noisy "
           "reference makes unbiased methods look biased)",
           ("tests/test_unbiased.py::test_agreement_has_its_size_and_power_on_synthetic_renders",
            "tests/test_suite_bias.py")),
    Mutant("tail-few-terms-counted", "experiments/lib/bias.py",
           "    used = pixels * (min(len(h) for h in halves) - 1) >= TAIL_TERMS\n",
           "    used = pixels > 0\n",
           "the heavy-tail check reads blocks of 1 to 7 varying pixels, where one deviation "
           "of light-tailed values holds most of the squares by chance: path, bsdf and mis "
           "on environment untestable for heavy tails they do not have",
           ("tests/test_suite_bias.py::test_blocks_of_few_varying_pixels_do_not_read_as_"
            "heavy_tails",)),
    Mutant("image-gate-off", "experiments/lib/bias_image.py",
           "        return self.top <= MAX_TERM_SHARE and self.own_dof >= MIN_DOF and \\\n",
           "        return self.own_dof >= MIN_DOF and \\\n",
           "the image test run whatever share of its variance one term holds: an image of "
           "infinite variance (rough glass sampled uniformly) reads low and is called biased",
           ("tests/test_suite_bias.py::test_an_image_ruled_by_infinite_variance_is_"
            "untestable_not_flagged",)),
    Mutant("own-dof-gate-off", "experiments/lib/bias_image.py",
           "        return self.top <= MAX_TERM_SHARE and self.own_dof >= MIN_DOF and \\\n",
           "        return self.top <= MAX_TERM_SHARE and \\\n",
           "the image test run on the renders' own variances however few degrees of freedom "
           "they have: samples of infinite variance read low and are called biased",
           ("tests/test_suite_bias_moments.py::test_infinite_variance_is_untestable_by_its_"
            "own_moments_too",)),
    Mutant("skew-gate-off", "experiments/lib/bias_image.py",
           "self.own_dof >= MIN_DOF and \\\n            self.own_skew <= MAX_SKEW",
           "self.own_dof >= MIN_DOF",
           "the image test run on a sum however skewed its renders' own third moments say it "
           "is: rare bright samples most renders miss read low, with a low variance, and a "
           "right method is called biased (veach_mis' cosine: -18%, p 5e-6)",
           ("tests/test_suite_bias_renders.py",)),
    Mutant("third-cumulant-of-a-sample", "experiments/lib/jobs.py",
           "    return mu3 * n * n / ((n - 1.0) * (n - 2.0)) / (n * n)",
           "    return mu3 * n * n / ((n - 1.0) * (n - 2.0))",
           "the skewness of a pixel's mean read from one sample's third cumulant (k3, not "
           "k3 / n^2): every image sum looks skewed and no cell is tested by its moments",
           ("tests/test_suite_bias_renders.py",)),
    Mutant("bias-renders-in-the-wrong-budget", "experiments/lib/studies/suite/measure.py",
           "(extra if budget == TIME else [])",
           "(extra if budget == SPP else [])",
           "the round's renders (at the equal-time count) added to the equal-spp renders: "
           "a budget of unequal counts, untestable however many renders it has",
           ("tests/test_suite_bias_renders.py",)),
    Mutant("bias-renders-at-equal-spp", "experiments/lib/studies/suite/bias_renders.py",
           "runs = measured.final(Cell(sp.name, name, declare.TIME))",
           "runs = measured.final(Cell(sp.name, name, declare.SPP))",
           "the round renders a void cell at its equal-spp count (16): it adds almost no "
           "samples where the tails need them",
           ("tests/test_suite_bias_renders.py",)),
    Mutant("hopeless-skew-over-samples", "experiments/lib/studies/suite/bias_renders.py",
           "test.own_skew / math.sqrt(gain) > 2.0 * bias_image.MAX_SKEW",
           "test.own_skew / gain > 2.0 * bias_image.MAX_SKEW",
           "the skewness after the round predicted to fall as one over the samples (not "
           "their square root): cells it cannot help render again, at a cost",
           ("tests/test_suite_bias_renders.py",)),
    Mutant("no-power-called-heavy-tails", "experiments/lib/studies/suite/bias_test.py",
           "    reason = \"\" if image.testable else \"heavy_tails\" if not image.size_holds "
           "else \"no_power\"\n",
           "    reason = \"\" if image.testable else \"heavy_tails\"\n",
           "a cell whose image test has no power called heavy-tailed: the report blames the "
           "method's tails for what its budget cannot show",
           ("tests/test_suite_bias_moments.py::test_a_known_variance_too_large_for_any_bias_"
            "is_no_power_not_heavy_tails",)),
    Mutant("own-variance-over-k", "experiments/lib/bias_image.py",
           "        c = share * share / v.shape[0] ** 2\n",
           "        c = share * share / v.shape[0]\n",
           "the variance of a mean of k renders taken as one render's over k, not k^2: "
           "the image test's variance k times too large, its power lost",
           ("tests/test_suite_bias_moments.py::test_bright_pixels_of_light_tails_are_tested_"
            "by_their_own_variances",)),
    Mutant("own-tails-ignored", "experiments/lib/studies/suite/bias_test.py",
           "        tails = max(tails, bias_image.own_tail_share(own, samples, varying))\n",
           "        tails = tails\n",
           "blocks whose renders' own samples say their variance rests on a few samples "
           "tested per block as long as no render rules their spread (environment's "
           "uniform+nee flagged by its pooled test in 2 of 20 draws)",
           ("tests/test_suite_bias_moments.py::test_blocks_whose_renders_all_caught_one_rare_"
            "sample_are_heavy_tailed",)),
    Mutant("suite-drops-own-variances", "experiments/lib/studies/suite/measure.py",
           "        renders = [[(x.image, x.spp, x.variance, x.variance_var, x.third)\n",
           "        renders = [[(x.image, x.spp)\n",
           "the suite hands the bias test its renders' images without their own variances: "
           "veach_mis' cells untestable again",
           ("tests/test_suite_bias_plugins.py::test_the_wrong_plugins_are_flagged_on_real_"
            "scenes_and_their_twins_are_not",)),
    Mutant("image-variance-one-side", "experiments/lib/bias_image.py",
           "    se2 = a.var + b.var + np.square(rounding * b.total)\n",
           "    se2 = b.var + np.square(rounding * b.total)\n",
           "the image test's variance without the method's share (heavy-tailed right "
           "methods called biased)",
           ("tests/test_suite_bias.py::test_heavy_tailed_blocks_are_tested_by_the_image_sum_"
            "with_its_size_and_power",)),
    Mutant("reference-cap-seconds-inverted", "experiments/lib/counts.py",
           "        affordable = max_seconds / seconds\n",
           "        affordable = seconds / max_seconds\n",
           "the reference's time allowance read upside down: a cheap reference never goes "
           "past its cap, an expensive one would",
           ("tests/test_suite.py::test_a_cheap_reference_is_extended_past_its_cap_as_far_"
            "as_its_seconds_go",)),
    Mutant("passes-of-the-lane-cap", "experiments/lib/jobs.py",
           "        if getattr(self.method, \"continues_sequence\", False) or power_of_two:\n",
           "        if getattr(self.method, \"continues_sequence\", False):\n",
           "a job of a power of two past the lane cap split at the cap (2427 + 1669): its "
           "timed render compiles Mitsuba's other kernel class, is discarded and rendered "
           "again (2.5 s per such cell of a cold make run)",
           ("tests/test_timing.py::test_a_job_of_a_power_of_two_past_the_lane_cap_renders_"
            "warm_in_passes_of_one",)),
    Mutant("view-warmed-every-time", "experiments/lib/execute.py",
           "    if warmed in _warmed or job.pilot:",
           "    if job.pilot:",
           "every view warmed up again each time its scene is loaded again: a trained "
           "guide's whole job rendered untimed once more per scene and budget (2.6-5.3 s "
           "per guiding scene of a cold make run)",
           ("tests/test_timing.py::test_a_view_made_again_is_not_warmed_again_but_for_a_"
            "new_kind_of_job",)),
    Mutant("pilot-warmed-up", "experiments/lib/execute.py",
           "    if warmed in _warmed or job.pilot:",
           "    if warmed in _warmed:",
           "a pilot warmed up before its one render: a pilot-sized render more per guiding "
           "scene of the default run",
           ("tests/test_timing.py::test_a_pilot_is_rendered_once_and_warms_the_jobs_after_it",)),
    Mutant("bias-sidak-missing", "experiments/lib/studies/suite/bias_test.py",
           "    return bias.sidak(1.0 - LEVEL, max(1, cells))",
           "    return 1.0 - LEVEL",
           "the run's bias tests each at 1%, the Sidak correction over the run's cells not "
           "applied (about one false 'biased' per 100 cells)",
           ("tests/test_suite_bias.py",)),
    Mutant("bias-learned-pixels", "experiments/lib/studies/suite/bias_test.py",
           "    return any(method.trains(r[1], pixels) for b in budgets for r in b)\n",
           "    return False\n",
           "a method that learns from its own samples tested on its pixels' spread where its "
           "renders trained (they share the learned guide: its blocks' variances too small, "
           "false 'biased')",
           ("tests/test_suite_bias.py",)),
    Mutant("cost-jitter-ignored", "experiments/lib/studies/suite/errors.py",
           "        if len(pooled) == len(clipped) and pooled[k][0] > var:",
           "        if False:",
           "a pair's cost variance from its own three renders only: a pair whose renders agree "
           "by chance claims a precision the machine does not have (textured_phong's A/A "
           "1.10 [1.04, 1.16] in one run, 0.93 [0.87, 0.98] in the next)",
           ("tests/test_suite_cost_jitter.py::test_a_pair_whose_renders_agree_by_chance_takes_the_scenes_jitter",)),
    Mutant("cost-jitter-pools-learners", "experiments/lib/studies/suite/analysis.py",
           "    jitter = errors.cost_jitter([c.runs[BUDGETS[0]] for c in cells.values() if not c.learns],",
           "    jitter = errors.cost_jitter([c.runs[BUDGETS[0]] for c in cells.values()],",
           "a learning method's costs, which vary with what each repeat learned, pooled as the "
           "machine's jitter: sunlit_room's A/A interval at hi/lo 1.7",
           ("tests/test_suite_cost_jitter.py::test_a_learning_methods_costs_stay_out_of_the_pool",)),
    Mutant("learner-untrained-inverted", "experiments/lib/studies/suite/analysis.py",
           "                [s for s, _, trained in rows if not trained]) for m, rows in out.items()}",
           "                [s for s, _, trained in rows if trained]) for m, rows in out.items()}",
           "the learner-over-plain finding names the scenes where the learner trained as the "
           "ones where it did not: a real loss of a trained guide read as the cells' noise",
           ("tests/test_suite.py::test_the_learner_finding_names_the_scenes_where_it_did_not_train",)),
    Mutant("learner-trained-at-equal-spp", "experiments/lib/studies/suite/measure.py",
           "    return any(method.trains(x.spp, pixels) for x in finals[TIME])",
           "    return any(method.trains(x.spp, pixels) for x in finals[SPP])",
           "whether a learner trained read from its equal-spp renders (a few dozen samples "
           "per pixel, never over the guide's thresholds): every scene's learner ratio called "
           "the cells' noise",
           ("tests/test_suite.py::test_a_learner_trained_where_its_equal_time_renders_did",)),
    Mutant("reach-ignored", "experiments/lib/studies/suite/bias_test.py",
           "            if c.status == \"biased\" and samples[name] * reach(name) < REACH_MIN else c",
           "            if c.status == \"biased\" and samples[name] < REACH_MIN else c",
           "a biased verdict kept whatever the method's reach of the scene's narrowest lobe: "
           "uniform+nee on Mitsuba's rough dielectric (Beckmann 0.02) called 54% biased, "
           "though correct",
           ("tests/test_bias_reach.py::test_only_a_biased_verdict_below_the_reach_is_void",)),
    Mutant("reach-glass-crossed-once", "experiments/lib/scene_probes.py",
           "        reach = min(reach, r * r if strategies.transmits(bsdf) else r)",
           "        reach = min(reach, r)",
           "a path through a closed glass object counted as crossing one narrow lobe, not two: "
           "its reach overstated by the lobe's (1/400 on rough_glass)",
           ("tests/test_bias_reach.py::test_a_path_crosses_a_glass_object_twice",)),
    Mutant("reach-core-whole-lobe", "experiments/lib/scene_probes.py",
           "        core = order[:np.searchsorted(carried, CORE_SHARE * carried[-1]) + 1]",
           "        core = order",
           "the core taken as the whole lobe (every BSDF draw): the reach of uniform sampling "
           "on a diffuse BSDF reads 1, not 1 - 1/sqrt(2)",
           ("tests/test_bias_reach.py::test_core_reach_of_known_lobes",)),
    Mutant("round-chosen-from-equal-time", "experiments/lib/studies/suite/bias_renders.py",
           "        worst = [predicted_error(measured.final(Cell(sp.name, n, declare.SPP)), ref,",
           "        worst = [predicted_error(measured.final(Cell(sp.name, n, declare.TIME)), ref,",
           "the A/A pair's round chosen from its equal-time renders' own errors: more renders "
           "pooled into a cell because its first draws caught a rare bright sample (its "
           "error biased low, optional stopping)",
           ("tests/test_suite_precision_round.py::test_the_round_is_chosen_from_the_equal_spp_"
            "renders_alone",)),
    Mutant("round-renders-not-pooled", "experiments/lib/studies/suite/measure.py",
           "    maps = [errors.pixel_map(x.variance, ref.image) for x in list(runs) + list(extra)]",
           "    maps = [errors.pixel_map(x.variance, ref.image) for x in list(runs)]",
           "the A/A pair's round rendered but left out of its expected error: its cost paid, "
           "its interval as wide as before",
           ("tests/test_suite_precision_round.py::test_the_rounds_renders_join_the_expected_"
            "error_and_not_the_costs",)),
    Mutant("flag-unconfirmed", "experiments/lib/studies/suite/bias_renders.py",
           '    return dataclasses.replace(first, status="unbiased", retest="not confirmed",\n',
           '    return dataclasses.replace(first, retest="not confirmed",\n',
           "a flag kept where fresh renders of the cell do not flag it again: a right method "
           "called biased by its first renders' chance draw against a low reference "
           "(mis+nee on veach_mis, +5.8%)",
           ("tests/test_suite_bias_retest.py",)),
    Mutant("flag-retest-pooled", "experiments/lib/studies/suite/study.py",
           "        again = measure.bias_tests(cfg, sp, measured, chunks, level, fresh, alone=True)\n",
           "        again = measure.bias_tests(cfg, sp, measured, chunks, level, fresh)\n",
           "a flag tested again on the fresh renders pooled with the first ones, which chose "
           "the cell: a chance flag comes back",
           ("tests/test_suite_bias_retest.py",)),
]
