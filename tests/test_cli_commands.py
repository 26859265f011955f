"""The process-model commands (layer, pulp, optimize), the bundled sieve example, the
module entry point, --version and the help text of every option."""

import argparse
import runpy
import subprocess
import sys

import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab import __version__
from tromplab.classifiers.layer import LayerModel
from tromplab.classifiers.pulp import PulpScreen
from tromplab.cli import build_parser, main

from .conftest import DATASETS, ROOT


def _walk(parser, path=("tromplab",)):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help for choice in action._choices_actions}
            for name, sub in action.choices.items():
                yield (*path, name), "(command)", helps.get(name)
                yield from _walk(sub, (*path, name))
        else:
            yield path, "/".join(action.option_strings) or action.dest, action.help


def test_every_command_and_option_has_help_text():
    missing = [f"{' '.join(path)} {option}" for path, option, text in _walk(build_parser()) if not (text and text.strip())]
    assert missing == []
    commands = {path[1] for path, _, _ in _walk(build_parser()) if len(path) > 1}
    assert {"fit", "layer", "pulp", "optimize", "sieve"} <= commands


@pytest.mark.slow
def test_version_and_module_entry_point(capsys):
    assert main(["--version"]) == 0  # main returns the exit code instead of raising SystemExit
    assert capsys.readouterr().out.strip() == f"tromplab {__version__}"
    done = subprocess.run([sys.executable, "-m", "tromplab", "--version"], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0 and done.stdout.strip() == f"tromplab {__version__}"
    bare = subprocess.run([sys.executable, "-m", "tromplab"], capture_output=True, text=True, cwd=ROOT)
    assert bare.returncode == 2 and "usage: tromplab" in bare.stdout


def test_layer_simulate_prints_and_writes_the_published_run(tmp_path, capsys):
    out = tmp_path / "layer.csv"
    assert main(["layer", "simulate", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    for step, value in ((50, 0.506), (100, 0.708), (200, 0.921), (300, 0.983)):  # spec section 7, computed from the model
        line = next(line for line in printed.splitlines() if line.strip().startswith(f"step {step:>5} ({step * 0.2:g} s)"))
        assert_allclose(float(line.split()[-1]), value, atol=5e-4)
    table = pd.read_csv(out)
    assert list(table.columns) == ["step", "time", "C_1", "C_2", "C_3", "C_4", "extraction", "locked"]
    assert_allclose(table["extraction"], LayerModel(0.005, 0.026, 0.21).simulate([0.5] * 4, 300).extraction)
    assert main(["layer", "simulate", "--linear", "--initial", "0.6,0.5,0.4", "--steps", "20", "--lock-threshold", "0.3"]) == 0
    assert "3 cells" in capsys.readouterr().out
    assert main(["layer", "simulate", "--diffusion", "0.6"]) == 2  # options out of range: usage errors
    assert "--diffusion, --segregation: 2 d + v0" in capsys.readouterr().err
    assert main(["layer", "simulate", "--passage", "1.5"]) == 2
    assert "argument --passage: must lie between 0 and 1, got 1.5" in capsys.readouterr().err
    assert main(["layer", "simulate", "--concentration", "1.5"]) == 2
    assert "argument --concentration: must lie between 0 and 1" in capsys.readouterr().err
    assert main(["layer", "simulate", "--concentration", "0"]) == 2
    assert "--concentration takes concentrations in 0..1, not all zero" in capsys.readouterr().err


@pytest.mark.slow
def test_layer_fit_recovers_the_published_parameters_from_the_bundled_example(tmp_path, capsys):
    out = tmp_path / "fit.csv"
    assert main(["layer", "fit", str(DATASETS / "layer_extraction_example.csv"), "-o", str(out)]) == 0
    table = pd.read_csv(out).set_index("parameter")
    # generated with d = 0.005, v0 = 0.026, vf0 = 0.21 and noise 0.005: each within its 95 % interval
    for name, true in (("diffusion", 0.005), ("segregation", 0.026), ("passage", 0.21)):
        assert table.loc[name, "low"] < true < table.loc[name, "high"], name
    assert_allclose(table.loc["segregation", "value"], 0.026, rtol=0.03)
    assert "segregation" in capsys.readouterr().out


def test_layer_fit_names_the_bad_row(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("step,extraction\n10,0.1\n20,1.4\n30,0.5\n40,0.6\n")
    assert main(["layer", "fit", str(bad)]) == 1
    error = capsys.readouterr().err
    assert "row 3" in error and "extraction" in error and "outside 0..1" in error
    bad.write_text("minute,extraction\n1,0.1\n")
    assert main(["layer", "fit", str(bad)]) == 1
    assert "give a 'step' column or a 'time' column" in capsys.readouterr().err


def test_pulp_optimum_matches_the_model(capsys):
    assert main(["pulp", "optimum", "--frequency", "10", "--applied", "1", "--phi", "0.0025"]) == 0
    printed = capsys.readouterr().out
    screen = PulpScreen(phi=0.0025)
    applied, rate = screen.best_pressure_drop(10.0)
    frequency, _, interior = screen.best_frequency(1.0)
    assert interior and f"H' = {applied:.5g}, productivity Q = {rate:.5g}" in printed and f"N = {frequency:.5g} 1/s" in printed
    assert main(["pulp", "optimum", "--applied", "1"]) == 0  # phi = 0: no interior maximum over N
    assert "no best frequency" in capsys.readouterr().out
    assert main(["pulp", "optimum"]) == 2
    assert "--frequency or --applied is needed" in capsys.readouterr().err
    assert main(["pulp", "optimum", "--frequency", "10", "--open-area", "-0.2"]) == 2
    assert "argument --open-area: must lie in (0, 1], got -0.2" in capsys.readouterr().err


def test_pulp_fit_recovers_the_generating_coefficients(tmp_path, capsys):
    out = tmp_path / "pulp.csv"
    assert main(["pulp", "fit", str(DATASETS / "pulp_screen_productivity_example.csv"), "--phi", "0.0025", "-o", str(out)]) == 0
    table = pd.read_csv(out).set_index("parameter")
    assert list(table.index) == ["beta", "lam"]
    assert_allclose(table["value"], [2.0, 3.0], rtol=0.02)  # generated with beta = 2, lam = 3 and 2 % noise
    assert (table["low"] < [2.0, 3.0]).all() and (table["high"] > [2.0, 3.0]).all()
    capsys.readouterr()
    assert main(["pulp", "fit", str(DATASETS / "pulp_screen_productivity_example.csv"), "--fit", "beta,gamma"]) == 2
    assert "--fit cannot fit gamma" in capsys.readouterr().err


@pytest.mark.slow
def test_optimize_reproduces_the_sieve_operating_point(tmp_path, capsys):
    out = tmp_path / "pareto.csv"
    assert main(["optimize", "-o", str(out), "--weights", "5"]) == 0
    printed = capsys.readouterr().out
    # docs/errata.md: the printed compromise (E 89.64 %, Q 1340 kg/h) is max Q at the 8 % purity limit, V ~ 0.080 m/s
    best_q = next(line for line in printed.splitlines() if "max Q" in line)
    assert "V = 0.080" in best_q and "E = 89.6" in best_q
    pareto = pd.read_csv(out)
    assert list(pareto.columns) == ["l1", "V", "Q", "E", "success"] and len(pareto) == 5
    assert pareto.sort_values("l1")["Q"].is_monotonic_increasing  # more weight on capacity, more capacity
    assert main(["optimize", "--speed-min", "0.3"]) == 2
    assert "--speed-min must be below --speed-max" in capsys.readouterr().err


def test_sieve_identify_recovers_the_published_velocity_laws_from_the_bundled_example(tmp_path, capsys):
    out = tmp_path / "laws.csv"
    assert main(["sieve", "identify", str(DATASETS / "sieve_identify_residues_example.csv"), "-o", str(out)]) == 0
    laws = pd.read_csv(out).set_index("fraction")
    # kinetics paper: 2.5x1.5 mm Vk 0.148, sigma 0.051; 2.0x1.5 mm Vk 0.185, sigma 0.069 m/s (residues rounded to 10 digits)
    assert_allclose(laws.loc["2.5x1.5", ["v_k", "sigma"]].astype(float), [0.148, 0.051], rtol=1e-6)
    assert_allclose(laws.loc["2.0x1.5", ["v_k", "sigma"]].astype(float), [0.185, 0.069], rtol=1e-6)


def test_bundled_model_examples_are_what_the_generator_writes(tmp_path, capsys):
    generator = runpy.run_path(str(ROOT / "analysis" / "make_model_examples.py"))
    generator["main"](["--outdir", str(tmp_path)])
    for name in ("sieve_identify_residues_example.csv", "layer_extraction_example.csv", "pulp_screen_productivity_example.csv"):
        assert (tmp_path / name).read_text() == (DATASETS / name).read_text(), name
