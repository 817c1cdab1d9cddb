"""The mutants of path guiding (its warps, model, recording, passes and study), a part of
:data:`tools.mutant_list.MUTANTS`: realistic bugs, one each (see that module)."""
from tools.mutant import Mutant

GUIDING = [
    Mutant("bench-frozen-cost-over-all-samples", "benchmarks/guiding.py",
           "    return recording, kernel_seconds * share / last\n",
           "    return recording, kernel_seconds * share / spp\n",
           "the bench's frozen pass cost divided over every sample of the job, not the last "
           "iteration's: a frozen guided pass reads far cheaper than it is, and issue 41's "
           "cost target holds on paper",
           ("tests/test_bench_guiding.py::test_pass_costs_split_the_kernel_time_by_the_"
            "passes_wall_time",)),
    Mutant("guide-kept-between-jobs", "integrators/guided_path.py",
           "        self.guide.reset()\n",
           "",
           "a job's schedule made without a new guide: a second mi.render with one "
           "integrator trains on the first job's samples (its training not counted) and "
           "looks up the first scene's leaves in another scene",
           ("tests/test_guide_model.py::test_each_job_learns_from_its_own_samples_alone",)),
    Mutant("guide-nested-records", "integrators/guided_path.py",
           "        if not self._rendering:\n",
           "        if False:\n",
           "vr_guided_path nested in another integrator (Mitsuba's moment or aov) records "
           "every sample it never learns from: silently untrained, and over the records' cap "
           "at a large count the render fails with advice about max_pass_spp",
           ("tests/test_guiding.py::test_nested_in_another_integrator_it_renders_plain_bsdf_"
            "sampling_and_says_so",)),
    Mutant("render-seed-python-only", "integrators/path.py",
           "    return int(seed) if isinstance(seed, int) else int(dr.slice(mi.UInt32(seed)))\n",
           "    return int(seed)\n",
           "a render's seed taken as a Python int only: nested in Mitsuba's aov, which passes "
           "a mi.UInt32 seed on, vr_guided_path and vr_adaptive fail with a TypeError",
           ("tests/test_guiding.py::test_nested_in_mitsubas_aov_integrator_its_image_is_its_"
            "trained_job",)),
    Mutant("guide-aov-warns", "integrators/guided_path.py",
           "        if not self._iterations:\n",
           "        if True:\n",
           "nested in Mitsuba's aov, whose image is the trained job's, vr_guided_path still "
           "warns that it cannot train (aov calls its sample for the AOVs): a false alarm",
           ("tests/test_guiding.py::test_nested_in_mitsubas_aov_integrator_its_image_is_its_"
            "trained_job",)),
    Mutant("guide-weights-own-pixels", "integrators/guide_passes.py",
           "        other = ~colour if (~colour).any() else colour\n",
           "        other = colour\n",
           "each pixel's combination weights read from its own checkerboard colour, its own "
           "samples among them: a group that missed rare bright samples reads a low "
           "variance and weighs more, and the image reads low",
           ("tests/test_guide_weights.py::test_cross_weights_keep_the_combined_image_"
            "unbiased",)),
    Mutant("guide-one-estimator-off-by-one", "integrators/guide_passes.py",
           "    if len(groups) == 1:\n",
           "    if len(groups) <= 2:\n",
           "the one-estimator shortcut (one weight of 1, no cross weights) taken for two "
           "estimators too: the second one's renders are dropped from the image, which is "
           "then noisier than the variance it states",
           ("tests/test_guide_weights.py::test_weights_sum_to_one_for_every_number_of_"
            "groups",)),
    Mutant("guide-share-missing", "integrators/guided.py",
           "        pdf = dr.select(s < 1.0, dr.fma(s, pdf_bsdf - p, p), pdf_bsdf)",
           "        pdf = dr.select(s < 1.0, (1.0 - s) * p, pdf_bsdf)",
           "the guided mixture's density without the BSDF's share (only the guide's part)",
           ("tests/test_guiding.py::test_drawn_pdf_and_weights",)),
    Mutant("guide-bin-solid-angle", "integrators/guide_warps.py",
           "    return 4.0 * math.pi / (res * res)",
           "    return 2.0 * math.pi / (res * res)",
           "a histogram bin's solid angle taken over the hemisphere (2 pi / res^2) though "
           "the bins tile the sphere (the density twice too high)",
           ("tests/test_guiding.py::test_guide_density_integrates_to_one",
            "tests/test_guiding.py")),
    Mutant("guide-alias-deficit-unpaid", "integrators/guide_warps.py",
           "        excess = excess - dr.select(last, 0.0, 1.0 - share)\n",
           "        excess = excess - dr.select(last | demoted, 0.0, 1.0 - share)\n",
           "an alias table whose next heavy bin does not pay a demoted heavy bin's deficit: "
           "it keeps more of its own slot than it has, and the guide draws its bins with "
           "other probabilities than its density states",
           ("tests/test_guide_alias.py::test_alias_tables_draw_the_histograms_probabilities",
            "tests/test_guiding.py::test_frozen_guide_draws_its_pdf")),
    Mutant("guide-alias-threshold-reversed", "integrators/guide_warps.py",
           "    index = dr.select(x - mi.Float(index) < entry.x, index, mi.UInt32(entry.y))",
           "    index = dr.select(x - mi.Float(index) < entry.x, mi.UInt32(entry.y), index)",
           "the alias draw keeps the bin where it should take its alias and the other way "
           "round",
           ("tests/test_guide_alias.py::test_drawn_bins_pass_a_chi_square",
            "tests/test_guiding.py::test_frozen_guide_draws_its_pdf")),
    Mutant("guide-record-wrong-vertex", "integrators/guide_record.py",
           "            after = L - dr.gather(mi.Color3f, self.radiance, slot, valid)\n",
           "            after = L\n",
           "every vertex files the path's whole radiance, its own NEE and what earlier "
           "vertices found included, instead of what arrived along its direction",
           ("tests/test_guiding.py::test_with_nee_the_guide_leaves_out_the_light_nee_samples",
            "tests/test_guiding.py::test_training_learns_the_sky_from_the_floor")),
    Mutant("guide-direct-wrong-vertex", "integrators/guide_record.py",
           "        slot = (depth - 1) * self.lanes + self.lane\n",
           "        slot = depth * self.lanes + self.lane\n",
           "the emission a direction found (which NEE samples too) filed under the vertex "
           "that found it, not the one whose direction found it: the guide learns direct "
           "light, which its records rate with the drawn MIS weight (textured_phong trained "
           "to the end at 0.39 of bsdf+nee's efficiency)",
           ("tests/test_guiding.py::test_with_nee_the_guide_leaves_out_the_light_nee_samples",)),
    Mutant("guide-mean-bakes-lanes", "integrators/guide_record.py",
           "        nee = channel_mean(L - ",
           "        nee = dr.mean(L - ",
           "a record's NEE share averaged with dr.mean, which writes the lane count into "
           "the render kernel: every training pass (each twice the last) compiles it again "
           "(0.4-1 s a pass on a cold kernel cache, hidden from the timed renders)",
           ("tests/test_guiding.py::test_no_recompile_between_passes",)),
    Mutant("guide-record-no-pdf", "integrators/guide_record.py",
           "        scale = beta * mi.Color3f(mi.unpolarized_spectrum(direction.weight)) "
           "* direction.pdf",
           "        scale = beta * mi.Color3f(mi.unpolarized_spectrum(direction.weight))",
           "records' radiance not divided by the sampling pdf (the guide learns the "
           "radiance times the density that sampled it)",
           ("tests/test_guiding.py::test_training_learns_the_sky_from_the_floor",)),
    Mutant("guide-record-densities-swapped", "integrators/guide_record.py",
           "mi.Vector2f(drawn.p_bsdf * rcp, drawn.p_guide * rcp)",
           "mi.Vector2f(drawn.p_bsdf * rcp, drawn.p_bsdf * rcp)",
           "the recorder takes the BSDF's density from the draw's record as the guide's too: "
           "every candidate share rates the same, and no unit learns to guide",
           ("tests/test_guiding.py::test_the_recorder_files_the_draws_densities",
            "tests/test_guiding.py::test_shares_go_down_where_guiding_helps")),
    Mutant("guide-draw-delta-densities", "integrators/guided.py",
           "        guide = GuideDraw(unit, ~use_bsdf, dr.select(delta, 0.0, pdf_bsdf),\n"
           "                          dr.select(delta, 0.0, p), delta)\n",
           "        guide = GuideDraw(unit, ~use_bsdf, pdf_bsdf, p, delta)\n",
           "the draw's record keeps the densities on a BSDF with a Dirac lobe, whose share is "
           "always 1: its smooth lobe's records rate the unit's candidate shares as if they "
           "could be guided",
           ("tests/test_guiding.py::test_a_draw_carries_what_it_drew",)),
    Mutant("guide-share-no-reweighting", "integrators/sdtree.py",
           "            dr.scatter_add(self.moments, x2 / dr.maximum(mix, 1e-20), row + k,",
           "            dr.scatter_add(self.moments, x2 / dr.maximum(dr.square(mix), 1e-20), "
           "row + k,",
           "the learned BSDF share's second moments averaged as if the records had been drawn "
           "from each candidate mixture ((F / p_s)^2), not reweighted by the density q they "
           "were drawn with (F^2 / (q p_s))",
           ("tests/test_guiding.py::test_share_moments_from_bsdf_drawn_records",)),
    Mutant("guide-roulette-unclamped", "integrators/guide_roulette.py",
           "        q = dr.clip(WINDOW * b * after / dr.maximum(reference, 1e-30), MIN_SURVIVAL,\n"
           "                    RR_MAX_PROBABILITY)",
           "        q = dr.maximum(WINDOW * b * after / dr.maximum(reference, 1e-30), MIN_SURVIVAL)",
           "the guided roulette's survival not clamped below 1: a path whose continuation "
           "matters goes on for sure but its throughput is still divided by the 'probability' "
           "(> 1), darkening what it brings",
           ("tests/test_guiding.py::test_roulette_survival_by_hand",
            "tests/test_guiding.py::test_blocks_agree_with_path")),
    Mutant("guide-roulette-weight", "integrators/path.py",
           "                rr_prob = dr.select(survival > 0, survival, rr_prob)\n"
           "            rr_continue = sampler.next_1d(active_next) < rr_prob\n",
           "                rr_continue = sampler.next_1d(active_next) < dr.select(\n"
           "                    survival > 0, survival, rr_prob)\n"
           "            else:\n"
           "                rr_continue = sampler.next_1d(active_next) < rr_prob\n",
           "the guided roulette decides with its own survival probability but the survivors "
           "are divided by the throughput rule's",
           ("tests/test_guiding.py::test_blocks_agree_with_path",)),
    Mutant("guide-stopped-rest-split", "integrators/guided_path.py",
           "        self._passes = guide_passes.merged_rest(self._passes, index)\n",
           "",
           "a guide whose training stopped renders the rest of its job in renders of "
           "max_pass_spp samples (many small renders: on veach_mis 26% more kernel time per "
           "sample than bsdf+nee for the same estimator)",
           ("tests/test_guiding.py::test_a_guide_that_learns_nothing_stops_and_renders_the_"
            "rest_in_one_pass",)),
    Mutant("guide-last-iteration-split", "integrators/guide_passes.py",
           "            for n in (split(it, most) if trains and k + 1 < len(counts) else [it])]\n",
           "            for n in (split(it, most) if trains else [it])]\n",
           "the last iteration of a training job, which records nothing, split into renders "
           "of max_pass_spp samples as if its records bounded its size",
           ("tests/test_guiding.py::test_only_recording_iterations_are_split_and_a_stop_"
            "merges_the_rest",)),
    Mutant("pass-parts-rounded", "experiments/lib/jobs.py",
           "                for p in ([n] if spec.rendered_count(n) == n else powers_of_two(n))]\n",
           "                for p in [n]]\n",
           "a multi-pass method's pass rendered whole with zsobol, which rounds its count up to "
           "a power of two: the job takes more of the sequence than it has (or than planned)",
           ("tests/test_guiding.py::test_a_pass_renders_in_counts_the_sampler_takes_exactly",
            "tests/test_guiding.py::test_guide_with_a_qmc_sampler_agrees_with_path")),
    Mutant("guide-records-not-pooled", "integrators/sdtree.py",
           "            energy = energy + self.kept_energy[:rows]\n",
           "",
           "a unit's histogram fitted to the last iteration's records alone while its counts "
           "are pooled (PPG's rebuild with a pooled record count)",
           ("tests/test_guide_model.py::test_every_iteration_s_records_are_pooled",)),
    Mutant("guide-pool-not-halved", "integrators/sdtree.py",
           "            kept = 0.5 * self.kept_energy[parent], 0.5 * self.kept_counts[parent]\n",
           "            kept = self.kept_energy[parent], self.kept_counts[parent]\n",
           "a split leaf hands each child all of its pooled sums (each counts the parent's "
           "records twice over against its own)",
           ("tests/test_guide_model.py::test_every_iteration_s_records_are_pooled",)),
    Mutant("guide-quadtree-option-ignored", "integrators/sdtree.py",
           "        if self.split_share > 0:\n",
           "        if False:\n",
           "directional_split accepted and never applied: the raw bins learned",
           ("tests/test_guide_model.py::test_the_integrator_fits_its_quadtree_to_the_pooled_"
            "records",)),
    Mutant("quadtree-leaf-energy-not-spread", "integrators/guide_quadtree.py",
           "        spread = np.repeat(np.repeat(nodes / (side * side), side, axis=1), side, axis=2)\n",
           "        spread = np.repeat(np.repeat(nodes, side, axis=1), side, axis=2)\n",
           "every bin of a quadtree leaf gets the leaf's whole energy (coarse leaves weigh "
           "their bins' count times too much)",
           ("tests/test_guide_model.py::test_quadtree_matches_a_recursive_oracle",)),
    Mutant("pilot-halved-across-training", "experiments/lib/engine.py",
           "        spp = fewer if trains(fewer) == trains(plain) else plain\n",
           "        spp = fewer\n",
           "a learning method's pilot at half the count even where that count does not "
           "train while the job does: its plain cost per sample would give the job about "
           "twice its time",
           ("tests/test_suite.py::test_a_learning_methods_equal_time_count_comes_from_its_"
            "pilot",)),
    Mutant("findings-untestable-counts-biased", "experiments/lib/studies/suite/words.py",
           "        untestable = sum(c.block_bias is not None and c.block_bias.status == \"untestable\"\n",
           "        untestable = sum(c.block_bias is not None and c.block_bias.status == \"biased\"\n",
           "the findings table counts the flagged cells as the untestable ones",
           ("tests/test_suite_bias.py::test_findings_table_rows_follow_each_scenes_verdicts",)),
    Mutant("findings-reasons-not-counted", "experiments/lib/studies/suite/bias_report.py",
           "        f\"{UNTESTABLE[reason]}: {count}\" for reason, count in reasons.most_common())\n",
           "        f\"{UNTESTABLE[reason]}: 1\" for reason, count in reasons.most_common())\n",
           "the findings name each reason for untestable cells without its count",
           ("tests/test_suite_bias.py::test_untestable_cells_are_counted_by_reason_and_their_"
            "table_named",)),
    Mutant("lab-verdict-chi-square-only", "experiments/lib/studies/lab/checks_report.py",
           "    if rejected or masses or albedos:\n",
           "    if rejected:\n",
           "the lab's conclusion verdict reads the chi-square alone (a density 10% high on a "
           "cap grid passes it and 'pass' would hide the mass check's failure)",
           ("tests/test_lab_checks.py::test_the_conclusion_verdict_carries_the_checks_the_"
            "chi_square_cannot_see",)),
    Mutant("bias-untrained-learner-renders", "experiments/lib/studies/suite/bias_test.py",
           "        not (method.learns and trained) else \"renders\"\n",
           "        not method.learns else \"renders\"\n",
           "a learning method's cell tested on its renders' spread (few degrees of freedom) "
           "even where no render trained and its pixels are independent (a guided cell at "
           "269 spp flagged by one block at p = 1.9e-7 that reruns did not repeat)",
           ("tests/test_suite_bias.py::test_a_learning_method_under_its_training_thresholds_"
            "is_tested_on_its_pixels",)),
    Mutant("cosine-product-off", "integrators/sdtree.py",
           "COSINE_PRODUCT = True\n",
           "COSINE_PRODUCT = False\n",
           "the guide learns the incident radiance alone, not times the cosine to the "
           "surface: unbiased, but 1.08 to 1.37 times more error per sample in the rooms",
           ("tests/test_guide_model.py",)),
    Mutant("cosine-product-wrong-class", "integrators/sdtree.py",
           "            learned = learned * class_cosines(self.res)[units % CLASSES]\n",
           "            learned = learned * class_cosines(self.res)[units % 3]\n",
           "the cosine taken to another normal class's axis than the unit's (a wall's "
           "histogram weighted as a floor's)",
           ("tests/test_guide_model.py",)),
    Mutant("executor-rest-unchecked", "experiments/lib/multipass.py",
           "    if sum(rest) != sum(schedule[index + 1:]) or any(n < 1 for n in rest):\n",
           "    if False:\n",
           "a method's replacement of its remaining passes accepted whatever samples it "
           "renders (a job's count silently changed)",
           ("tests/test_guiding.py::test_the_executor_refuses_a_rest_that_changes_the_"
            "samples",)),
    Mutant("guide-variance-from-passes", "experiments/lib/multipass.py",
           "    sq, passes = done * mean * mean, 1\n",
           "    sq, passes = done * mean * mean, len(spps)\n",
           "a guided job's per-pixel variance taken from the spread of its passes, as if the "
           "untrained and the trained ones were one estimator (the suite's error of "
           "guided+nee twice too high on hidden_lamp), where it states none",
           ("tests/test_clock.py",)),
    Mutant("guide-variance-ignored", "experiments/lib/multipass.py",
           "    variance = getattr(integrator, \"combined_variance\", None)\n",
           "    variance = None\n",
           "the guided integrator's variance of its combined image not used: the suite's "
           "per-pixel errors of guided+nee lost (its errors from 3 repeats, bounds only)",
           ("tests/test_guiding.py::test_the_executor_takes_the_combined_variance",)),
    Mutant("guide-moments-misread", "integrators/guided_path.py",
           "        at = -len(MOMENT_AOVS) + 3 * (power - 1)\n",
           "        at = -len(MOMENT_AOVS) + 3 * power\n",
           "each render's moments read one AOV group too far (the cubes as the mean squares): "
           "the combined variance and its stated tails wrong",
           ("tests/test_guiding.py::test_combined_moments_pool_each_groups_renders_by_their_"
            "samples",)),
    Mutant("guided-render-untrained", "integrators/guided_path.py",
           "        if self._driven or not develop:",
           "        if True:",
           "one mi.render call with vr_guided_path (a user's own scene) renders one untrained "
           "pass: plain BSDF sampling, and the moment AOVs in the image",
           ("tests/test_guiding.py::test_one_mi_render_trains_the_guide_in_its_own_passes",)),
    Mutant("record-split-ignores-the-film", "integrators/guided_path.py",
           "        most = min(self.max_pass_spp,\n"
           "                   max(1, guide_record.most_spp(pixels, self.record_depth)))\n",
           "        most = self.max_pass_spp\n",
           "a recording render of max_pass_spp samples per pixel whatever the film: a user's "
           "512 x 512 render with vr_guided_path refused for its records' memory",
           ("tests/test_guiding.py::test_a_large_film_records_in_renders_that_fit_the_cap",)),
    Mutant("learner-count-across-regimes", "experiments/lib/counts.py",
           "    if trains(count) == trains(pilot_spp):",
           "    if True:",
           "a learning method's count from its pilot's cost kept where it falls in the other "
           "training regime: on glossy_indirect 532 spp that do not train, or 913 that train at "
           "1.75 times the budget, as the rounding of its short renders' cost goes",
           ("tests/test_learner_counts.py",)),
    Mutant("learner-pilot-below-its-thresholds", "experiments/lib/engine.py",
           "        if not trains(plain):       # it does not train at its budget: their cost is its cost",
           "        if False:",
           "a pilot rendered for a learning method that cannot train at its budget: its count "
           "rests on one render's cost (grazing: 97 or 174 spp by the machine's spell)",
           ("tests/test_learner_counts.py::test_a_learner_that_cannot_train_at_its_budget_renders_no_pilot",)),
    Mutant("learner-untrained-count-exact", "experiments/lib/engine.py",
           "            return plain if trains(rounded) else rounded",
           "            return plain",
           "a learning method that does not train at its budget counted exactly, not rounded "
           "as the plain method it then is: another count (and, not a power of two, a render "
           "kernel 1.7% dearer per sample) for the same estimator",
           ("tests/test_learner_counts.py::test_a_learner_that_cannot_train_at_its_budget_renders_no_pilot",)),
]
