"""Hostile command lines and outputs: exit codes, options named, nothing half
written, previous results kept, distinct figure names, safe expressions."""

import pandas as pd
import pytest

from tromplab.classifiers.sieve import fit_dependence
from tromplab.cli import main

SIZES = (10, 20, 40, 80, 160, 320)
CURVE = (0.97, 0.9, 0.7, 0.35, 0.1, 0.02)


def points_file(tmp_path, experiments, name="points.csv"):
    rows = [f"{e},{s},{p}" for e, curve in experiments.items() for s, p in zip(SIZES, curve)]
    path = tmp_path / name
    path.write_text("experiment,size,partition_fine\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize(
    "option, value",
    [("--alpha", "2"), ("--alpha", "nan"), ("--ci", "1.5"), ("--bootstrap", "-1"), ("--bootstrap", "10000000"),
     ("--seed", "-3"), ("--delta-max", "-5"), ("--delta-max", "inf"), ("--jobs", "-1"), ("--min-feed-share", "2")],
)  # fmt: skip
def test_option_out_of_range_is_a_usage_error_naming_the_option(tmp_path, capsys, option, value):
    out = tmp_path / "out"
    assert main(["fit", str(points_file(tmp_path, {"A": CURVE})), "-o", str(out), option, value]) == 2
    err = capsys.readouterr().err
    assert option in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(
    "argv",
    [["sieve", "pg", "--hole", "nan", "--length", "1", "--width", "1", "--cell-width", "3"], ["sieve", "bin", "--decks", "0",
     "--length", "1", "--recovery", "0.9"]],
)  # fmt: skip
def test_sieve_options_are_checked_by_the_parser(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert ("--hole" in err or "--decks" in err) and "Traceback" not in err


def test_flat_experiment_is_a_failure_and_the_rest_is_a_partial_result(tmp_path, capsys):
    out = tmp_path / "out"
    path = points_file(tmp_path, {"good": CURVE, "flat": (0.4,) * 6})
    assert main(["fit", str(path), "-o", str(out), "--no-figures"]) == 3
    failures = pd.read_csv(out / "failures.csv")
    assert list(failures["experiment"]) == ["flat"] and "flat" in failures["reason"][0]
    fits = pd.read_csv(out / "fits.csv")
    assert not fits.loc[fits["experiment"] == "flat", "adequate"].any()
    assert fits.loc[fits["experiment"] == "flat", "rank"].isna().all()
    assert "partial result" in capsys.readouterr().err


def test_nothing_fitted_is_bad_input_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fit", str(points_file(tmp_path, {"flat": (0.4,) * 6})), "-o", str(out)]) == 1
    assert "no formula could be fitted" in capsys.readouterr().err
    assert not out.exists()


def test_a_failed_run_leaves_the_previous_outputs_whole(tmp_path, monkeypatch):
    out = tmp_path / "out"
    assert main(["fit", str(points_file(tmp_path, {"A": CURVE})), "-o", str(out), "--no-figures"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if not p.name.startswith(".")}

    def broken(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(pd.DataFrame, "to_csv", broken)
    assert main(["fit", str(points_file(tmp_path, {"B": CURVE}, "other.csv")), "-o", str(out), "--no-figures"]) == 70
    monkeypatch.undo()
    after = {p.name: p.read_bytes() for p in out.iterdir() if not p.name.startswith(".")}
    assert after == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".") and p.is_dir() and "out" in p.name]


@pytest.mark.slow
def test_a_rerun_replaces_the_figures_of_the_previous_run(tmp_path):
    out = tmp_path / "out"
    assert main(["fit", str(points_file(tmp_path, {"A": CURVE, "B": CURVE})), "-o", str(out), "--formulas", "plitt"]) == 0
    assert (out / "curves_B.png").exists()
    assert main(["fit", str(points_file(tmp_path, {"A": CURVE}, "a.csv")), "-o", str(out), "--formulas", "plitt"]) == 0
    assert sorted(p.name for p in out.glob("curves_*.png")) == ["curves_A.png"]


@pytest.mark.slow
def test_distinct_experiments_never_share_a_figure(tmp_path):
    out = tmp_path / "out"
    names = {"Проба 1": CURVE, "Образец 1": CURVE, "../evil": CURVE, "$x_{50}^2$": CURVE}
    assert main(["fit", str(points_file(tmp_path, names)), "-o", str(out), "--formulas", "plitt"]) == 0
    mapping = pd.read_csv(out / "figures.csv")
    assert sorted(mapping["experiment"]) == sorted(names)
    assert mapping["file"].is_unique
    assert all((out / name).exists() and "/" not in name for name in mapping["file"])
    assert not (tmp_path / "evil.png").exists()


def test_output_folder_that_is_a_file_or_holds_the_input_is_refused(tmp_path, capsys):
    path = points_file(tmp_path, {"A": CURVE})
    clash = tmp_path / "taken"
    clash.write_text("mine")
    assert main(["fit", str(path), "-o", str(clash)]) == 1
    assert clash.read_text() == "mine"
    assert main(["fit", str(path), "-o", str(tmp_path)]) == 1
    assert "holds the input" in capsys.readouterr().err
    assert main(["points", str(path), "-o", str(path)]) == 1


@pytest.mark.parametrize("form", ["open('/etc/passwd')", "c0 + c1.__class__", "__import__('os')", "c0 + (lambda: 1)()"])
def test_dependence_expressions_allow_only_arithmetic(form):
    with pytest.raises(ValueError):
        fit_dependence([2.0, 2.0, 2.0], [1.0, 1.5, 2.0], [0.1, 0.12, 0.15], form=form)


def test_rank_table_with_a_missing_cell_is_refused(tmp_path, capsys):
    table = tmp_path / "F.csv"
    table.write_text("experiment,equation,F,n\n1,3,10,8\n1,7,12,8\n2,3,9,8\n")  # formula (7) missing in experiment 2
    assert main(["rank", str(table), "-o", str(tmp_path / "r")]) == 1
    assert "F.csv" in capsys.readouterr().err


@pytest.mark.slow
def test_outputs_are_byte_identical_whatever_the_hash_seed(tmp_path):
    """Same input and seed, same bytes, whatever PYTHONHASHSEED."""
    import os
    import subprocess
    import sys

    path = points_file(tmp_path, {"Проба 1": CURVE, "B": (0.99, 0.95, 0.8, 0.4, 0.15, 0.05)})
    runs = []
    for hash_seed in ("1", "4242"):
        out = tmp_path / f"out{hash_seed}"
        env = {**os.environ, "PYTHONHASHSEED": hash_seed}
        command = [sys.executable, "-m", "tromplab", "fit", str(path), "-o", str(out), "--formulas", "plitt,lognormal,5",
                   "--bootstrap", "20", "--seed", "7", "--quiet"]  # fmt: skip
        done = subprocess.run(command, env=env, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        runs.append({p.name: p.read_bytes() for p in sorted(out.iterdir()) if not p.name.startswith(".")})
    assert runs[0].keys() == runs[1].keys() and len(runs[0]) >= 5
    assert runs[0] == runs[1]


def _model_command_argvs(tmp_path, output):
    """Each command that writes one file or folder, with ``output`` as its -o."""
    from pathlib import Path

    datasets = Path(__file__).resolve().parents[1] / "datasets"
    fits = tmp_path / "fits.csv"
    fits.write_text("experiment,formula,d_cut\nA,(3),100\n", encoding="utf-8")
    return {
        "layer simulate": ["layer", "simulate", "--steps", "5", "-o", str(output)],
        "layer fit": ["layer", "fit", str(datasets / "layer_extraction_example.csv"), "-o", str(output)],
        "pulp fit": ["pulp", "fit", str(datasets / "pulp_screen_productivity_example.csv"), "-o", str(output)],
        "optimize": ["optimize", "--weights", "2", "-o", str(output)],
        "export": ["export", str(fits), "--to", "csv-long", "-o", str(output)],
        "trend": ["trend", str(datasets / "classifier_trend_surveys.csv"), "-o", str(output), "--no-figures"],
    }


@pytest.mark.parametrize("clash", ["folder", "under a file"])
@pytest.mark.parametrize(
    "command", ["layer simulate", "layer fit", "pulp fit", "optimize", "export", "trend"]
)  # fmt: skip
def test_every_command_checks_its_output_path_before_any_work(tmp_path, capsys, command, clash):
    """As ``fit``: exit 1, the option named, nothing written, before any fitting or simulation."""
    blocker = tmp_path / "blocker"
    if clash == "folder":  # a folder where a file goes; for trend (a folder output) a file where the folder goes
        blocker.mkdir() if command != "trend" else blocker.write_text("mine")
        output = blocker
    else:
        blocker.write_text("mine")
        output = blocker / "result"
    argv = _model_command_argvs(tmp_path, output)[command]
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert ("--output" in captured.err or "--outdir" in captured.err) and "Traceback" not in captured.err
    assert "Wrote" not in captured.out and captured.out.strip() == ""  # refused before any work was printed
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert blocker.is_dir() or blocker.read_text() == "mine"


@pytest.mark.skipif(__import__("os").geteuid() == 0, reason="root may write anywhere")
def test_an_unwritable_output_folder_is_refused_before_any_work(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        assert main(["layer", "simulate", "--steps", "5", "-o", str(locked / "run.csv")]) == 1
        assert "permission denied" in capsys.readouterr().err
    finally:
        locked.chmod(0o700)


@pytest.mark.parametrize(
    "argv, option",
    [(["layer", "simulate", "--cells", "1"], "--cells"), (["layer", "simulate", "--cells", "10000000"], "--cells"),
     (["layer", "simulate", "--steps", "0"], "--steps"), (["layer", "simulate", "--steps", "1e12"], "--steps"),
     (["layer", "simulate", "--step-seconds", "-1"], "--step-seconds"), (["layer", "simulate", "--diffusion", "nan"], "--diffusion"),
     (["layer", "simulate", "--lock-threshold", "2"], "--lock-threshold"), (["layer", "simulate", "--initial", "0.5"], "--initial"),
     (["layer", "simulate", "--initial", "0.5,x"], "--initial"), (["layer", "fit", "data.csv", "--level", "1"], "--level"),
     (["pulp", "optimum", "--frequency", "0"], "--frequency"), (["pulp", "optimum", "--applied", "-1"], "--applied"),
     (["pulp", "optimum", "--applied", "1", "--tau", "inf"], "--tau"), (["pulp", "fit", "data.csv", "--level", "0"], "--level"),
     (["optimize", "--weights", "1"], "--weights"), (["optimize", "--capacity-share", "0"], "--capacity-share"),
     (["optimize", "--min-efficiency", "101"], "--min-efficiency"), (["optimize", "--purity-limit", "1"], "--purity-limit"),
     (["optimize", "--width", "0"], "--width"), (["optimize", "--speed-max", "nan"], "--speed-max")],
)  # fmt: skip
def test_model_command_options_out_of_range_are_usage_errors(capsys, argv, option):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert option in err and "Traceback" not in err


@pytest.mark.parametrize(
    "options, expected",
    [(["--bootstrap", "100000"], "--bootstrap 100,000 on 270 fits means 27,000,000 refits"),
     (["--bootstrap", "10000000"], "argument --bootstrap: is capped at 100,000 resamples"),
     (["--jobs", "100000"], "argument --jobs: is capped at 4,096"), (["--jobs", "1e9"], "argument --jobs: is capped")],
)  # fmt: skip
def test_absurd_bootstrap_or_jobs_requests_are_refused_before_any_work(tmp_path, capsys, options, expected):
    """30 experiments x 9 formulas: 100,000 resamples each would be 27 million refits (about 3 hours)."""
    import time

    path = points_file(tmp_path, {f"E{k}": CURVE for k in range(30)})
    out = tmp_path / "out"
    start = time.monotonic()
    assert main(["fit", str(path), "-o", str(out), *options]) == 2
    assert time.monotonic() - start < 5  # refused from the request's size, not after fitting
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.slow
def test_verbose_adds_log_lines_of_each_step_and_quiet_removes_the_tables(tmp_path, capsys):
    path = points_file(tmp_path, {"A": CURVE, "B": CURVE[::-1]})
    printed = {}
    for flags in ([], ["-v"], ["-vv"], ["-q"]):
        assert main([*flags, "fit", str(path), "-o", str(tmp_path / "out"), "--no-figures", "--bootstrap", "3"]) == 0
        printed[" ".join(flags)] = capsys.readouterr()
    default, verbose, debug, quiet = printed[""], printed["-v"], printed["-vv"], printed["-q"]
    assert "tromplab." not in default.err
    for step in ("tromplab.loading.tables: read", "tromplab.loading.lab:", "tromplab.workbench: fitting 2 experiment(s) x 9 formula(s)",
                 "tromplab.statistics.uncertainty: intervals for 18 fit(s)", "tromplab.output.outputs: swapped the new outputs into"):  # fmt: skip
        assert step in verbose.err, step
    assert "chunk 1/1 fitted" not in verbose.err and "chunk 1/1 fitted: 18 fits" in debug.err  # -vv: debug lines too
    assert "bootstrap A plitt: 3 residuals resamples" in debug.err
    assert verbose.out == default.out  # the log goes to stderr only
    # --quiet: only errors and the one-line result (on standard output, where the result goes)
    assert quiet.out.count("\n") == 1 and quiet.out.startswith("tromplab fit: 2 experiment(s) fitted") and default.out.strip()
    assert len(quiet.err) <= len(default.err)
    import logging

    assert not logging.getLogger("tromplab").handlers  # removed after the command


@pytest.mark.slow
def test_a_short_seeded_cli_fuzz_run_finds_nothing(monkeypatch):
    """benchmarks/fuzz_cli.py for 30 runs: mutated bundled tables and options through main()."""
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "fuzz_cli.py"
    spec = importlib.util.spec_from_file_location("fuzz_cli", path)
    fuzz_cli = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "fuzz_cli", fuzz_cli)  # dataclasses look their module up
    spec.loader.exec_module(fuzz_cli)
    outcomes = fuzz_cli.fuzz(seed=3, runs=30)
    assert len(outcomes) == 30
    findings = [f"{o.label}: {' '.join(o.argv)} {o.mutations}\n{o.stderr[-500:]}" for o in outcomes if o.finding]
    assert not findings, "\n".join(findings)
    assert {o.code for o in outcomes} >= {0, 1}  # both outcomes reached: the mutations are neither all harmless nor all fatal


@pytest.mark.parametrize("column", ["step", "time"])
def test_layer_fit_refuses_a_step_beyond_the_simulated_range(tmp_path, capsys, column):
    """Found by benchmarks/fuzz_cli.py: a step of 1e308 overflowed the integer steps (exit 70)."""
    data = tmp_path / "layer.csv"
    data.write_text(f"{column},extraction\n1,0.1\n2,0.2\n1e308,0.5\n", encoding="utf-8")
    assert main(["layer", "fit", str(data), "-o", str(tmp_path / "fit.csv")]) == 1
    err = capsys.readouterr().err
    assert f"row 4, column '{column}'" in err and "at most 1,000,000 are simulated" in err and "Traceback" not in err
    assert not (tmp_path / "fit.csv").exists()


def test_trend_refuses_a_survey_cut_short(tmp_path, capsys):
    """Found by benchmarks/fuzz_cli.py: a survey with one point ended in exit 70."""
    from pathlib import Path

    source = Path(__file__).resolve().parents[1] / "datasets" / "classifier_trend_surveys.csv"
    text = source.read_text(encoding="utf-8").rstrip("\n").split("\n")
    data = tmp_path / "surveys.csv"
    data.write_text("\n".join([*text, "S99,2025-12-01,38.0,0.81"]) + "\n", encoding="utf-8")
    assert main(["trend", str(data), "-o", str(tmp_path / "out"), "--no-figures"]) == 1
    err = capsys.readouterr().err
    assert "survey 'S99' has 1 point(s); each survey needs at least 3" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()
