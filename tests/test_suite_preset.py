"""The suite's ``--preset``: ``paper`` sets its values, an explicit option wins over it,
``default`` leaves every setting as without ``--preset``, a bad name is refused naming the
valid ones, and run_all passes ``--preset`` on to the suite."""
from __future__ import annotations

import dataclasses

import pytest

import scenes
from experiments import run_all
from experiments.lib import studies
from experiments.lib.studies.suite import study as S
from experiments.lib.studies.suite import declare as suite_plan

CBOX = scenes.path("suite/cbox.xml")


def _settings(tmp_path, *argv):
    return S.settings(S.parse(["--scenes", CBOX, "--out", str(tmp_path), *argv]))


def _films(cfg):
    return [(sp.width, sp.height) for sp in suite_plan.plan_scenes(cfg)]


def test_paper_preset_sets_its_values_and_scales_the_film_up(tmp_path):
    cfg = _settings(tmp_path, "--preset", "paper")
    paper = S.PRESETS["paper"]
    for key in ("max_size", "min_size", "spp", "time_budget", "repeats", "reference_spp",
                "reference_max_spp"):
        assert getattr(cfg, key) == paper[key], key
    assert _films(cfg) == [(256, 128)]               # cbox.xml's 64 x 32, scaled up
    # negative control: without the preset the film is scaled down to --max-size 48
    assert _films(_settings(tmp_path)) == [(48, 24)]


def test_an_explicit_option_wins_over_the_preset(tmp_path):
    cfg = _settings(tmp_path, "--repeats", "5", "--preset", "paper", "--max-size", "128",
                    "--reference-max-spp", "8192")
    assert (cfg.repeats, cfg.max_size, cfg.reference_max_spp) == (5, 128, 8192)
    assert (cfg.spp, cfg.time_budget, cfg.reference_spp) == (256, 0.5, 4096)   # the preset's
    assert _films(cfg) == [(128, 64)]                 # min-size 256, capped by --max-size


def test_default_preset_changes_nothing(tmp_path):
    plain, default = _settings(tmp_path), _settings(tmp_path, "--preset", "default")
    fields = [f.name for f in dataclasses.fields(plain) if f.name != "executor"]
    assert {f: getattr(default, f) for f in fields} == {f: getattr(plain, f) for f in fields}
    assert (plain.max_size, plain.min_size, plain.spp, plain.repeats) == (S.MAX_SIZE, 0, 16, 3)
    # negative control: the comparison sees a preset's change
    paper = _settings(tmp_path, "--preset", "paper")
    assert {f: getattr(paper, f) for f in fields} != {f: getattr(plain, f) for f in fields}


def test_a_bad_preset_is_refused_naming_the_valid_ones(tmp_path, capsys):
    with pytest.raises(SystemExit):
        S.parse(["--preset", "poster", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert "poster" in err and "'default'" in err and "'paper'" in err


def test_run_all_passes_the_preset_on_to_the_suite(tmp_path):
    suite = next(s for s in studies.ordered() if s.name == S.NAME)
    args = run_all.build_parser().parse_args(["--preset", "paper", "--out", str(tmp_path)])
    args.explicit = {"preset"}
    argv = run_all.sub_argv(args, suite)
    assert argv[argv.index("--preset") + 1] == "paper"
    args.explicit = set()                              # negative control: not given, not passed
    assert "--preset" not in run_all.sub_argv(args, suite)


def test_the_default_run_renders_the_adaptive_method_and_given_methods_win(tmp_path):
    """The suite's default methods include bsdf+nee+adaptive, in ``make run`` and in
    ``make full`` alike (run_all --full passes the suite nothing: it has no --full), and
    methods given explicitly win."""
    suite = next(s for s in studies.ordered() if s.name == S.NAME)
    for extra in ([], ["--full"]):
        args = run_all.cli.parse_args(run_all.build_parser(), extra + ["--out", str(tmp_path)])
        argv = run_all.sub_argv(args, suite)
        assert "--full" not in argv
        assert S.ADAPTIVE_METHOD in S.parse(argv).methods
    given = S.parse(["--methods", "bsdf,path", "--out", str(tmp_path)])
    assert given.methods == ["bsdf", "path"]
