"""The mutants of ``make mutants`` (:mod:`tools.mutants`): realistic bugs, one each.

Every entry replaces one exact piece of the source with a mistake that a careful author
could make and that changes what the code computes (never a mere refactoring): the kind
of bug each test family exists to catch. ``first`` names the test files or ids run first.
"""
from tools.mutant import Mutant
from tools.mutant_list_adaptive import ADAPTIVE
from tools.mutant_list_bias import BIAS
from tools.mutant_list_guiding import GUIDING

MUTANTS = [
    # ------------------------------------------------------------ plugins: the estimator
    Mutant("rr-eta", "integrators/path.py",
           "beta[rr_active] *= dr.rcp(dr.maximum(rr_prob, warps.PDF_EPSILON))",
           "beta[rr_active] *= dr.rcp(dr.maximum(dr.minimum(beta_max, RR_MAX_PROBABILITY), "
           "warps.PDF_EPSILON))",
           "Russian roulette divides by a survival probability without eta^2 while the "
           "survival test keeps it (too bright inside glass)",
           ("tests/test_unbiased.py::test_bsdf_with_nee_is_mitsubas_path_sample_for_sample", "tests/test_unbiased.py")),
    Mutant("nee-balance", "integrators/path.py",
           "warps.power_heuristic(ds_em.pdf, vertex.em_pdf))",
           "ds_em.pdf / (ds_em.pdf + vertex.em_pdf))",
           "next-event estimation weighted by the balance heuristic while BSDF hits keep the "
           "power heuristic: the two MIS weights no longer sum to one",
           ("tests/test_unbiased.py::test_bsdf_with_nee_is_mitsubas_path_sample_for_sample", "tests/test_unbiased.py")),
    Mutant("mixture-weight", "integrators/strategies.py",
           "        return value, warps.mixture_pdf(self.weight, self.a.pdf(bsdf, ctx, si, wo, "
           "active),\n                                        pdf_b)",
           "        return value, warps.mixture_pdf(1.0 - self.weight, self.a.pdf(bsdf, ctx, "
           "si, wo, active),\n                                        pdf_b)",
           "the mixture's weight uses the other technique's share (1 - c instead of c)",
           ("tests/test_strategy_warps.py", "tests/test_mis.py")),
    Mutant("sided-half", "integrators/warps.py",
           "return dr.select(both_sides, 0.5 * mirrored,",
           "return dr.select(both_sides, mirrored,",
           "the two-sided hemisphere density forgets the 1/2 of the side choice "
           "(transmitting BSDFs with uniform and cosine sampling)",
           ("tests/test_warps.py", "tests/test_strategy_warps.py")),
    Mutant("phong-warp", "integrators/warps.py",
           "cos_alpha = dr.power(u.x, dr.rcp(exponent + 1.0))",
           "cos_alpha = dr.power(u.x, dr.rcp(exponent + 2.0))",
           "the Phong lobe warp inverts the CDF of cos^(n+1) (the BRDF's normalisation taken "
           "for the lobe's)",
           ("tests/test_warps.py", "tests/test_phong.py")),
    Mutant("phong-sampled-lobe-pdf", "integrators/phong.py",
           "        pdf = self._pdf(p_glossy, wo, glossy_pdf)\n        active &=",
           "        pdf = dr.select(glossy, p_glossy * glossy_pdf, (1.0 - p_glossy) * "
           "warps.square_to_cosine_hemisphere_pdf(wo))\n        active &=",
           "the writeup's bug: the density of the lobe that drew the sample instead of the "
           "mixture's (pixels darken as spp grows)",
           ("tests/test_phong.py",)),
    Mutant("phong-normalisation", "integrators/phong.py",
           "f = kd * dr.inv_pi + ks * ((n + 2.0) / (n + 1.0)) * glossy_pdf",
           "f = kd * dr.inv_pi + ks * glossy_pdf",
           "the glossy lobe normalised by (n + 1) / 2 pi (the sampling density's) instead of "
           "(n + 2) / 2 pi (energy off by (n + 2) / (n + 1))",
           ("tests/test_phong.py",)),
    Mutant("hemisphere-weight-pdf", "integrators/strategies.py",
           "        return weighted_direction(bsdf, ctx, si, wo, self.pdf(bsdf, ctx, si, wo, "
           "active),\n                                  active)",
           "        return weighted_direction(bsdf, ctx, si, wo, 1.1 * self.pdf(bsdf, ctx, si, "
           "wo, active),\n                                  active)",
           "uniform and cosine sampling weight their directions by a density 10% above the "
           "one their pdf reports (every weight 10% low: darker with more samples; a "
           "chi-square test of pdf cannot see it)",
           ("tests/test_lab_checks.py",)),
    Mutant("eta-inverted", "integrators/strategies.py",
           "return dr.select(crosses & (bs.eta > 0), bs.eta, 1.0)",
           "return dr.select(crosses & (bs.eta > 0), dr.rcp(bs.eta), 1.0)",
           "the relative index of refraction of a sampled crossing taken the wrong way round",
           ("tests/test_strategy_warps.py", "tests/test_unbiased.py")),
    # ------------------------------------------------------------ plugins: the samplers
    Mutant("halton-dimension", "integrators/halton.py",
           "                                  self._pixel_seed, self.randomization)\n"
           "        self._dimension += 1",
           "                                  self._pixel_seed, self.randomization)\n"
           "        self._dimension += 2",
           "halton's dimension counter advanced twice per draw (every other prime base "
           "skipped: an off-by-one in the dimension bookkeeping)",
           ("tests/test_halton.py",)),
    Mutant("halton-offset", "integrators/sequence_sampler.py",
           "return self._sample_offset + self._pass_offset + self._lane_sample",
           "return self._pass_offset + self._lane_sample",
           "the sequence samplers' base (halton's state) ignores sample_offset: a continued "
           "sequence starts over at every job",
           ("tests/test_experiments.py::test_passes_of_a_continuing_sampler_continue_one_sequence",
            "tests/test_halton.py")),
    Mutant("pass-dimension", "integrators/sequence_sampler.py",
           "        self._dimension = dr.zeros(mi.UInt32, dr.width(self._dimension))\n"
           "        self._advanced()",
           "        self._advanced()",
           "the sequence samplers' advance() keeps the dimension counter: a declared pass "
           "draws its camera sample from the dimensions where the previous pass stopped",
           ("tests/test_sequence_sampler.py", "tests/test_halton.py")),
    Mutant("zsobol-matrix", "integrators/qmc_sobol.py",
           "v = v ^ ((v >> 4) & 0x0F0F0F0F)",
           "v = v ^ ((v >> 4) & 0x0F0F0F0E)",
           "one entry of Sobol's second generator matrix wrong",
           ("tests/test_zsobol.py",)),
    Mutant("zsobol-dimension", "integrators/zsobol.py",
           "                                 self.randomization)\n        self._dimension += 2",
           "                                 self.randomization)\n        self._dimension += 1",
           "zsobol's next_2d advances one dimension instead of two (successive pairs overlap)",
           ("tests/test_zsobol.py::test_next_2d_counts_two_dimensions", "tests/test_zsobol.py")),
    # ------------------------------------------------------------ experiments
    Mutant("relmse-denominator", "experiments/lib/metrics.py",
           "    err = np.square(np.asarray(image, np.float64) - ref) / (ref * ref + eps)",
           "    err = np.square(np.asarray(image, np.float64) - ref) / (ref + eps)",
           "relMSE divided by ref + eps instead of ref^2 + eps",
           ("tests/test_experiments.py::test_metrics_against_hand_computed_values",
            "tests/test_references.py")),
    Mutant("normal-quantile", "experiments/lib/stats.py",
           "half = _t_quantile(dof, level) * math.sqrt(total)",
           "half = 1.959964 * math.sqrt(total)",
           "intervals from the normal quantile instead of Student's t (too narrow at 3-4 "
           "repeats)",
           ("tests/test_stats.py",)),
    Mutant("verdict-inverted", "experiments/lib/stats.py",
           "return ratio_interval([mse_b, seconds_b], [mse_a, seconds_a], level)",
           "return ratio_interval([mse_a, seconds_a], [mse_b, seconds_b], level)",
           "the efficiency ratio A / B computed as B / A (every verdict names the wrong winner)",
           ("tests/test_convergence.py", "tests/test_samplers_study.py")),
    Mutant("floor-forgotten", "experiments/lib/stats.py",
           "    floor = float(floor)\n    value = float(x.mean()) - floor",
           "    floor = 0.0\n    value = float(x.mean()) - floor",
           "the reference's own expected error is not subtracted",
           ("tests/test_convergence.py", "tests/test_samplers_study.py")),
    Mutant("variance-dof", "experiments/lib/jobs.py",
           "s2 = np.maximum(self.sq - self.spp * self.mean ** 2, 0.0) / (self.passes - 1)",
           "s2 = np.maximum(self.sq - self.spp * self.mean ** 2, 0.0) / self.passes",
           "the per-pixel variance of a reference from its passes divided by n, not n - 1 "
           "(the floor under every error too small)",
           ("tests/test_experiments.py::test_accumulator_is_the_weighted_average_of_pass_images",
            "tests/test_references.py", "tests/test_convergence.py")),
    Mutant("warm-timing-off", "experiments/lib/execute.py",
           "        if not timed.compiled:\n",
           "        if True:\n",
           "warm timing switched off: a render that compiled its kernel is kept and timed",
           ("tests/test_timing.py",)),
    Mutant("clock-forgets-host", "experiments/lib/clock.py",
           "    return float(result.kernel_seconds + result.host_seconds)",
           "    return float(result.kernel_seconds)",
           "the clock leaves out a method's host work between its passes (a learning method's "
           "table building looks free)",
           ("tests/test_clock.py",)),
    Mutant("clock-last-pass", "experiments/lib/execute.py",
           "        kernels += kernel\n",
           "        kernels = kernel\n",
           "only the last pass's kernels are timed (a training pass looks free)",
           ("tests/test_clock.py",)),
    Mutant("lab-mass-against-one", "experiments/lib/studies/lab/mass.py",
           "    return check(mass, share, rel, quad, z)",
           "    return check(mass, 1.0, rel, quad, z)",
           "the lab's mass check compares the density's integral with 1 instead of the share "
           "of directions drawn (a BSDF's own sampling that fails some samples is flagged)",
           ("tests/test_lab_checks.py::test_mass_is_compared_with_the_share_drawn_not_with_one",
            "tests/test_lab_checks.py")),
    Mutant("integrator-kept", "experiments/lib/execute.py",
           "    integrator = mi.load_dict(spec)",
           "    integrator = fresh_integrator.__dict__.setdefault(job.method.name,\n"
           "                                                      mi.load_dict(spec))",
           "one integrator kept per method across jobs (a learning method starts its second "
           "job trained)",
           ("tests/test_clock.py",)),
    Mutant("engine-efficiency-floor", "experiments/lib/measurements.py",
           "        ea, eb = ([getattr(r[rung], metric) - self.floor(c, metric) for r in self.runs[c]]",
           "        ea, eb = ([getattr(r[rung], metric) - 0.0 for r in self.runs[c]]",
           "the engine's efficiency forgets the reference's floor: a method near the "
           "reference's noise looks no better than one far above it",
           ("tests/test_engine.py",)),
    Mutant("engine-equal-time-floor", "experiments/lib/counts.py",
           "        spp = 2 ** max(0, round(math.log2(max(spp, 1.0))))",
           "        spp = 2 ** max(0, int(math.log2(max(spp, 1.0))))",
           "an equal-time count rounded down to a power of two instead of to the nearest "
           "(cheap methods get up to half their budget)",
           ("tests/test_suite.py::test_equal_time_count_is_the_budgets_power_of_two",
            "tests/test_engine.py")),
    Mutant("key-forgets-seed", "experiments/lib/plan.py",
           "    digest = hashlib.sha256(json.dumps([fields, variant, plugins_version()],",
           "    digest = hashlib.sha256(json.dumps([{k: v for k, v in fields.items() "
           "if k != \"seed\"}, variant, plugins_version()],",
           "a store key that forgets the seed (two repeats would share one entry)",
           ("tests/test_experiments.py::test_job_keys_change_with_everything_the_image_depends_on",)),
    # ------------------------------------------------------------ the suite's precise errors
    Mutant("pass-variance-dof", "experiments/lib/jobs.py",
           "        s2 = np.maximum(self.sq - self.spp * self.mean ** 2, 0.0) / (self.passes - 1)",
           "        s2 = np.maximum(self.sq - self.spp * self.mean ** 2, 0.0) / self.passes",
           "the per-pixel variance from the passes' spread divided by the passes, not passes - 1 "
           "(the suite's expected relMSE 25% low with 4 passes)",
           ("tests/test_suite_errors.py",)),
    Mutant("pooled-variance-per-pixel", "experiments/lib/studies/suite/errors.py",
           "        var = float(v.var(axis=0, ddof=1).sum()) / (repeats * n * n)",
           "        var = float(v.var(axis=0, ddof=1).mean()) / repeats",
           "the pooled error's variance is one pixel's, not that of the mean over the pixels "
           "(intervals about sqrt(N) times too wide: nothing is ever decided)",
           ("tests/test_suite_errors.py",)),
    Mutant("log-interval-normal", "experiments/lib/stats.py",
           "    half = math.sqrt(total) * _t_quantile(dof, level)",
           "    half = math.sqrt(total) * normal_quantile(level)",
           "the suite's combined efficiency interval takes the normal quantile even where a "
           "term has few degrees of freedom (the paired costs' 2R - 2)",
           ("tests/test_stats.py",)),
    # ------------------------------------------------------------ path guiding
    *GUIDING,
    # ------------------------------------------------------------ the bias test
    *BIAS,
    # ------------------------------------------------------------ the suite's errors
    Mutant("moments-count-missing", "experiments/lib/execute.py",
           "        sq += k * (m2 if per_sample else image * image)",
           "        sq += (m2 if per_sample else k * image * image)",
           "the samples' mean squares added without their count: the per-pixel variances "
           "of a vr_moments render wrong by the sample count",
           ("tests/test_suite_errors.py",)),
    Mutant("tails-ignored", "experiments/lib/studies/suite/errors.py",
           "        var = own if math.isnan(var) else max(var, own)",
           "        var = var",
           "the renders' own variances of their errors (from their samples' fourth moments) "
           "left out: where a few pixels rule a cell's error its interval rests on three "
           "values of each and is far too narrow",
           ("tests/test_error_tails.py",)),
    Mutant("combined-tails-unweighted", "experiments/lib/multipass.py",
           "    return sum(w ** 4 * variance_of_variance(m1, m2, m3, m4, n)",
           "    return sum(w ** 2 * variance_of_variance(m1, m2, m3, m4, n)",
           "a guided job's groups' variances of their variances weighted as the variances "
           "are (w^2), not as their squares (w^4)",
           ("tests/test_error_tails.py",)),
    Mutant("kurtosis-dropped", "experiments/lib/jobs.py",
           "    return (2.0 * s2 * s2 / (n - 1) + excess / n) / (n * n)",
           "    return (2.0 * s2 * s2 / (n - 1)) / (n * n)",
           "the variance of a pixel's variance from the normal theory alone: a pixel ruled "
           "by rare bright samples reads ten times surer than it is",
           ("tests/test_error_tails.py",)),
    Mutant("moments-rounding-unbounded", "experiments/lib/jobs.py",
           "    excess = np.maximum(mu4 - 3.0 * mu2 * mu2 - rounding, 0.0)",
           "    excess = np.maximum(mu4 - 3.0 * mu2 * mu2, 0.0)",
           "the fourth central moment read from single-precision sums taken at face value: "
           "smooth pixels' rounding read as heavy tails",
           ("tests/test_error_tails.py",)),
    Mutant("adaptive-nested-plain", "integrators/adaptive.py",
           "        raise ValueError(\"vr_adaptive: called by another integrator (its sample(), not its \"\n",
           "        return self.nested.sample(scene, sampler, ray, medium, active)\n"
           "        raise ValueError(\"vr_adaptive: called by another integrator (its sample(), not its \"\n",
           "vr_adaptive nested in Mitsuba's moment hands out its nested integrator's plain "
           "samples: no pilot, no counts, and no word of it",
           ("tests/test_adaptive.py::test_nested_in_another_integrator_it_is_refused_by_name",)),
    Mutant("precision-scale-linear", "experiments/lib/studies/suite/precision.py",
           "    scale = (error / precision) ** 2",
           "    scale = error / precision",
           "the precision rule's factor not squared (the standard error falls as "
           "1/sqrt(samples)): scenes ruled by rare samples get too few",
           ("tests/test_suite_errors.py",)),
    Mutant("bias-calibration-ignored", "experiments/lib/studies/suite/bias_test.py",
           "    if own is None or own.status == \"unbiased\":",
           "    if True:",
           "the test's own calibration ignored: where the reference method fails its own test "
           "(a heavy-tailed reference), other methods are still called biased against it",
           ("tests/test_suite_bias.py",)),
    Mutant("cost-spike-unclipped", "experiments/lib/studies/suite/errors.py",
           "    return np.split(stats.winsorize(np.concatenate(devs)),",
           "    return np.split(np.concatenate(devs),",
           "the paired costs' plain variance: one render slowed 2x by the machine widens an "
           "A/A efficiency interval to hi/lo ~2",
           ("tests/test_suite_errors.py",)),
    Mutant("cost-budgets-equal-weight", "experiments/lib/studies/suite/errors.py",
           "    weight = (share_a / share_a.sum() + share_b / share_b.sum()) / 2",
           "    weight = np.full(len(budgets), 1 / len(budgets))",
           "each budget's cost deviations weighted alike, not by its share of the seconds: "
           "the short equal-spp renders count as much as the equal-time ones the seconds "
           "measure (intervals too narrow: a synthetic learning method's holds its truth "
           "too rarely)",
           ("tests/test_suite_errors.py::test_a_cost_per_sample_that_differs_between_budgets_is_not_noise",)),
    Mutant("figure-tmp-left", "experiments/lib/figure_pool.py",
           "                os.remove(tmp)",
           "                pass",
           "a worker killed past its deadline leaves its half-written temporary file beside "
           "the figure",
           ("tests/test_figure_pool.py::test_a_figure_past_its_deadline_is_named_and_its_worker_ended",)),
    Mutant("pilot-count-rounded", "experiments/lib/engine.py",
           "        count = counts.equal_time_spp(seconds, piloted, False, budget.max_spp)",
           "        count = counts.equal_time_spp(seconds, piloted, True, budget.max_spp)",
           "a learning method's equal-time count rounded to the nearest power of two: it gets "
           "0.71 to 1.41 times the budget, and its efficiency, which grows with its count, "
           "follows the rounding",
           ("tests/test_suite.py::test_a_learning_methods_equal_time_count_comes_from_its_pilot",)),
    Mutant("ladder-learner-stretches", "experiments/lib/engine.py",
           "                if budget.ladder and method.learns:",
           "                if budget.ladder and method.learns and budget.ladder[-1] < 2:",
           "a learning method's ladder planned as stretches that accumulate (the convergence "
           "study's ladder as it was: each rung too short to train, the guide never acts)",
           ("tests/test_one_loop.py",)),
    Mutant("ladder-learner-accumulated", "experiments/lib/engine.py",
           "                independent = bool(budgets[name].ladder) and \\\n",
           "                independent = False and \\\n",
           "a learning method's rungs (one training job each) accumulated into one image as "
           "if they were stretches of one render",
           ("tests/test_one_loop.py",)),
    Mutant("sequence-passes-spread", "experiments/lib/engine.py",
           "                spread = not declaration.method(cell.method).continues_sequence",
           "                spread = True",
           "a zsobol job's passes (parts of one Owen-scrambled Sobol' sequence) read as "
           "independent: their spread taken for the image's variance, the cell's error from it",
           ("tests/test_engine.py::test_a_runs_variance_comes_only_from_independent_passes",)),
    Mutant("verdict-by-a-firefly", "experiments/lib/studies/suite/ratios.py",
           "        return self.side == \"\" and self.est.known and self.est.lo > 1 and self.firm",
           "        return self.side == \"\" and self.est.known and self.est.lo > 1",
           "a method found more efficient by an interval that one render's rare firefly "
           "makes (two renders of one estimator 177 times apart)",
           ("tests/test_suite_fireflies.py",)),
    Mutant("tail-rest-keeps-the-top", "experiments/lib/studies/suite/errors.py",
           "    v[r][p] = 0.0\n",
           "    pass\n",
           "the rest of an error that one pixel of one render rules keeps that term: the "
           "bound on the efficiency is the mean-based interval's end, which a firefly in "
           "the baseline puts above 1 for one estimator",
           ("tests/test_suite_tail_bounds.py",)),
    Mutant("tail-bound-on-the-wrong-side", "experiments/lib/studies/suite/ratios.py",
           "    if errors.ruled(b):       # b's error at least its rest: a at least this "
           "efficient",
           "    if errors.ruled(a):       # b's error at least its rest: a at least this "
           "efficient",
           "a firefly in the baseline's renders bounds the efficiency from above instead "
           "of below",
           ("tests/test_suite_tail_bounds.py",)),
    Mutant("typical-by-the-mean", "experiments/lib/studies/suite/errors.py",
           "    return float(np.median(b.each) * np.mean(b.seconds) /\n"
           "                 (np.median(a.each) * np.mean(a.seconds)))",
           "    return float(np.mean(b.each) * np.mean(b.seconds) /\n"
           "                 (np.mean(a.each) * np.mean(a.seconds)))",
           "the typical ratio read from the renders' mean error, which the firefly rules too: "
           "every verdict firm",
           ("tests/test_suite_fireflies.py",)),
    Mutant("unreachable-lights-with-nee", "experiments/lib/studies/suite/words.py",
           "             and m.strategy is not None and not m.nee]",
           "             and m.strategy is not None]",
           "methods with next-event estimation said to miss the scene's point lights",
           ("tests/test_suite.py::test_methods_without_nee_are_said_to_miss_a_scenes_delta_"
            "lights",)),
    Mutant("reference-recorded-short", "experiments/lib/references.py",
           "            self.record(spec, self.read(spec, None) if self.cached(spec) > len(js) else\n"
           "                        self.read_jobs(js, spec.method.name))",
           "            self.record(spec, self.read_jobs(js, spec.method.name))",
           "a reference that an earlier declaration extended is recorded with the chunks a later "
           "one asked for (its JSON and image shorter than it is: the suite's bias round did so)",
           ("tests/test_references.py::test_rendered_once_then_extended_without_rerendering",)),
    Mutant("against-reference-not-rendered-on", "experiments/lib/studies/suite/reference_choice.py",
           "        _render_on(study, cfg, refs, sp.bias_ref)\n",
           "",
           "path's reference, which every cell's bias test on a stand-in's scene reads, left at "
           "its first size however one chunk's pixel rules it",
           ("tests/test_reference_choice.py",)),
    Mutant("candidate-void-kept", "experiments/lib/studies/suite/reference_choice.py",
           '        if test.reason != "heavy_tails" or k == AGAINST_DOUBLINGS or \\\n',
           '        if True or k == AGAINST_DOUBLINGS or \\\n',
           "a candidate reference whose own few chunks hold one rare bright path left void, "
           "not rendered on: the scene keeps path's noisier reference (veach_mis in two cold "
           "runs)",
           ("tests/test_reference_choice.py::test_a_candidate_whose_own_tails_void_its_test_renders_on_until_it_is_testable",)),
    Mutant("candidate-rejection-retried", "experiments/lib/studies/suite/reference_choice.py",
           '        if test.reason != "heavy_tails" or k == AGAINST_DOUBLINGS or \\\n',
           '        if test.status == "unbiased" or k == AGAINST_DOUBLINGS or \\\n',
           "a candidate reference that failed its test rendered on and tested again: a second "
           "try at every rejection raises the chance of adopting a wrong reference",
           ("tests/test_reference_choice.py::test_a_candidate_whose_own_tails_void_its_test_renders_on_until_it_is_testable",)),
    # ------------------------------------------------------------ adaptive sampling
    *ADAPTIVE,
    # ------------------------------------------------------------ the suite's reference
    Mutant("reference-unproven", "experiments/lib/studies/suite/reference_choice.py",
           '        if test.status == "unbiased":',
           '        if test.status != "untestable":',
           "the best sampler's reference stands in for path's without passing the bias test "
           "against it: a wrong candidate moves every error of its scene",
           ("tests/test_reference_choice.py::test_a_wrong_candidate_is_rejected_and_path_kept",)),
    Mutant("reference-header-ignored", "experiments/lib/studies/suite/reference_choice.py",
           "    if header is not None and header.methods and not header.renders(method.name):",
           "    if header is not None and not header.methods:",
           "the candidate reference tried on a scene whose header leaves its method out (a "
           "guiding scene's errors then against a method it never compares)",
           ("tests/test_reference_choice.py::test_a_scene_that_leaves_the_candidate_out_keeps_paths",)),
    # ------------------------------------------------------------ the sampler study's pick
    Mutant("pick-largest-estimate", "experiments/lib/studies/sampler_comparison/analysis.py",
           "        chosen = tied[-1]",
           "        chosen = top",
           "the sampler the other studies add is the largest estimate even where the study "
           "cannot tell it from others: a re-measurement that swaps two tied estimates "
           "changes the suite's and the convergence study's methods",
           ("tests/test_samplers_study.py::test_the_pick_among_tied_samplers_survives_a_re_measurement_that_swaps_them",)),
    Mutant("pick-deterministic", "experiments/lib/studies/sampler_comparison/analysis.py",
           "        at = [r for r in rows if r.depth == depth and not kinds[r.sampler].deterministic\n"
           "              and r.relative_efficiency.known]",
           "        at = [r for r in rows if r.depth == depth and r.relative_efficiency.known]",
           "a deterministic sampler (one run for every repeat, no interval of its own) can be "
           "the pick the suite and the convergence study add",
           ("tests/test_samplers_study.py::test_the_pick_among_tied_samplers_survives_a_re_measurement_that_swaps_them",)),
    # ------------------------------------------------------------ the figure pool
    Mutant("figures-during-renders", "experiments/lib/execute.py",
           "    figure_pool.wait()                  # no figure is drawn while a render is timed",
           "    pass",
           "a render started while worker processes still draw figures: its kernel time (the "
           "clock) counts their load on the cores",
           ("tests/test_figure_pool.py::test_a_render_waits_for_the_figures_handed_over",)),
    Mutant("warm-up-at-one-spp", "experiments/lib/execute.py",
           "        return 4 if power_of_two else 5",
           "        return 1 if power_of_two else 5",
           "the warm-up at 1 spp for every power of two: on a Gaussian film a 16-spp render "
           "compiles another kernel, so its first timed try is thrown away",
           ("tests/test_timing.py::test_the_warm_up_count_compiles_the_kernel_of_the_timed_count",)),
    # ------------------------------------------------------------ the adaptive sweep
    Mutant("adaptive-sweep-twin-swapped", "experiments/lib/sweeps/adaptive_pilot.py",
           "        whole = [ratio(a, b) for a, b in zip(err[adaptive(m)], err[m])]",
           "        whole = [ratio(a, b) for a, b in zip(err[m], err[adaptive(m)])]",
           "the adaptive sweep divides the plain method's relMSE by its adaptive twin's: "
           "where the pilot misleads the allocation, the sweep reports a gain",
           ("tests/test_sweeps.py::test_adaptive_sweep_finds_where_the_pilot_misleads_it",)),
    Mutant("dark-pixels-brightest", "experiments/lib/sweeps/adaptive_pilot.py",
           '    mask[np.argsort(lum, axis=None, kind="stable")[:k]] = True',
           '    mask[np.argsort(lum, axis=None, kind="stable")[-k:]] = True',
           "the adaptive sweep's dark pixels are the brightest ones, where the floor never "
           "serves",
           ("tests/test_sweeps.py::test_dark_mask_is_the_darkest_share_of_the_reference",)),
    Mutant("scene-hash-absolute", "experiments/lib/scenes.py",
           "        relative = os.path.relpath(os.path.abspath(f), root).replace(os.sep, \"/\")",
           "        relative = os.path.abspath(f)",
           "a multi-file scene's hash over its files' absolute paths: its references' keys and "
           "seeds differ between two clones of the project",
           ("tests/test_scene_hash.py",)),
]
