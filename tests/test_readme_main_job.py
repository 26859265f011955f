"""The README's main job shows the headline feature: every experiment's best fit
gets a finite interval for its cut and Ep, every share written lies in [0, 1], the bundled
data set is what its generator writes, and the double-deck data say what they cannot tell."""

import math
import re
import shlex
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from tromplab.cli import main

from .conftest import ROOT

DATA = ROOT / "datasets" / "air_classifier_lab_synthetic.csv"


def readme_main_job() -> list[str]:
    """The main job's arguments, found as .ci/run finds them (the part after '&&')."""
    line = next(line for line in (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
                if re.match(r"^python -m pip install \. && tromplab ", line))  # fmt: skip
    return shlex.split(line.split("&& ", 1)[1])[1:]


def documented_share_columns() -> set[str]:
    """The columns docs/columns.md gives the unit 0..1 or the range [0, 1] (shares, probabilities)."""
    found = set()
    for line in (ROOT / "docs" / "columns.md").read_text(encoding="utf-8").splitlines():
        cells = [cell.strip() for cell in line.split("|")[1:-1]]
        if len(cells) >= 4 and (cells[2] == "0..1" or cells[3].startswith("[0, 1]")):
            found.update(re.findall(r"`([a-z_<>]+)`", cells[0]))
    return found


@pytest.fixture(scope="module")
def main_job(tmp_path_factory):
    folder = tmp_path_factory.mktemp("main_job")
    arguments = readme_main_job()
    assert arguments[:2] == ["fit", "datasets/air_classifier_lab_synthetic.csv"] and "--ci" in arguments
    arguments[1] = str(DATA)
    arguments[arguments.index("-o") + 1] = str(folder / "results")
    return folder / "results", arguments


@pytest.mark.slow
def test_the_main_job_prints_and_writes_a_finite_cut_interval_for_every_best_fit(main_job, capsys):
    results, arguments = main_job
    assert main(arguments) == 0
    printed = capsys.readouterr()
    assert printed.err == ""  # nothing to warn of: every cut is bracketed, the stated yields agree
    fits = pd.read_csv(results / "fits.csv")
    best = fits[fits["rank"] == 1]
    assert sorted(best["experiment"]) == ["t1_ammophos", "t3_quartz", "t6_nepheline", "t8_graphite"]
    for column in ("d_cut", "ep"):
        low, high = best[f"{column}_low"], best[f"{column}_high"]
        assert np.isfinite(low).all() and np.isfinite(high).all()
        assert (low < best[column]).all() and (best[column] < high).all()
    assert printed.out.count("  intervals:") == 4 and "d50 low  d50 high" in printed.out and "ep low  ep high" in printed.out
    assert not (results / "warnings.csv").exists()


@pytest.mark.slow
def test_every_share_the_main_job_writes_lies_in_0_1(main_job):
    results, arguments = main_job
    if not (results / "fits.csv").exists():
        assert main(arguments) == 0
    shares = documented_share_columns()
    assert {"eta", "akaike_share", "weight_<formula>", "runs_p"} <= shares
    checked = 0
    for name in ("fits.csv", "averages.csv"):
        table = pd.read_csv(results / name)
        for column in table.columns:
            stem = re.sub(r"_(low|high)$", "", column)
            if stem in shares or (column.startswith("weight_") and "weight_<formula>" in shares):
                values = table[column].dropna().to_numpy(dtype=float)
                assert ((values >= 0) & (values <= 1)).all(), (name, column, values[(values < 0) | (values > 1)])
                checked += 1
    assert checked >= 15


def test_the_bundled_data_set_is_what_its_generator_writes(tmp_path):
    target = tmp_path / "lab.csv"
    subprocess.run([sys.executable, str(ROOT / "analysis" / "make_classifier_lab_example.py"), "--output", str(target)],
                   check=True, capture_output=True)  # fmt: skip
    assert target.read_bytes() == DATA.read_bytes()
    header = [line for line in DATA.read_text(encoding="utf-8").splitlines() if line.startswith("#")]
    assert any("SYNTHETIC" in line and "seed 2018" in line for line in header)
    assert any("doi:10.17588/2072-2672.2018.6.015-023" in line for line in header)


def test_the_cut_sizes_are_the_published_ones_and_the_measured_sizes_bracket_them():
    published = pd.read_csv(ROOT / "datasets" / "shuvalov2018_table1_experiments.csv", comment="#")
    cuts = dict(zip(published["experiment"], published["d_cut_um"]))
    lab = pd.read_csv(DATA, comment="#")
    for line in DATA.read_text(encoding="utf-8").splitlines():
        found = re.match(r"#   (t\d_\w+) \((\d+), .*\): ([\d.]+), ", line)
        if found:
            name, number, cut = found.group(1), int(found.group(2)), float(found.group(3))
            assert math.isclose(cut, cuts[number]), name
            rows = lab[lab["experiment"] == name]
            assert rows["size_lower_um"].min() < cut / 4 and rows["size_upper_um"].max() > cut * 2.5


def test_the_console_says_when_the_yield_was_estimated_with_its_value_and_standard_error(tmp_path, capsys):
    from tromplab.loading.lab import read_experiments

    assert main(["fit", str(DATA), "-o", str(tmp_path / "est"), "--size-unit", "um", "--estimate-yield",
                 "--formulas", "plitt", "--no-figures"]) == 0  # fmt: skip
    err = " ".join(capsys.readouterr().err.split())
    balances = read_experiments(DATA, estimate_yield=True).balances
    assert "note: 4 of 4 experiments: the fine yield was estimated by least squares from the three streams" in err
    for balance in balances:  # all four named (not "and 1 more"), each with its value and standard error
        estimate = balance.yield_estimate
        assert f"{balance.experiment} {estimate.value:.4f} +/- {estimate.stderr:.4f}" in err
        assert balance.fine_yield == estimate.value and balance.yield_source == "least-squares estimate"
    said = pd.read_csv(tmp_path / "est" / "warnings.csv")
    assert list(said["code"]) == ["yield-estimated"] * 4
    one = DATA.read_text(encoding="utf-8").split("t3_quartz,", 1)[0]  # the header and the first test only
    (tmp_path / "one.csv").write_text(one, encoding="utf-8")
    assert main(["fit", str(tmp_path / "one.csv"), "-o", str(tmp_path / "one"), "--estimate-yield", "--formulas", "plitt",
                 "--no-figures"]) == 0  # fmt: skip
    (estimate,) = [b.yield_estimate for b in balances[:1]]
    line = " ".join(capsys.readouterr().err.split())
    assert line.startswith(f"note (t1_ammophos): fine yield estimated by least squares from the three streams: "
                           f"{estimate.value:.4f} +/- {estimate.stderr:.4f} (standard error, ")  # fmt: skip


@pytest.mark.slow
def test_the_double_deck_data_say_what_they_cannot_tell(tmp_path, capsys):
    lab = ROOT / "datasets" / "double_deck_screen_decks_lab.csv"
    assert main(["fit", str(lab), "-o", str(tmp_path / "decks"), "--size-unit", "mm", "--ci", "0.95", "--no-figures"]) == 0
    printed = capsys.readouterr()
    err = " ".join(printed.err.split())
    assert "warning: 2 of 2 experiments: the cut is not bracketed by the data" in err and "no interval is given for them" in err
    fits = pd.read_csv(tmp_path / "decks" / "fits.csv")
    best = fits[fits["rank"] == 1]
    assert best["d_cut_low"].isna().all() and best["ep_low"].isna().all()
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "double_deck_screen_decks_lab.csv -o decks --size-unit mm --ci 0.95   # what the data cannot tell" in readme


def test_the_coverage_stated_in_the_docs_for_weighed_and_estimated_yields():
    """docs/uncertainty.md: the true formula's 95 % cut interval covers the true cut in 3 of 4
    tests with the weighed yields, 2 of 4 with the yields estimated from the streams."""
    import tromplab

    truth = {}
    for line in DATA.read_text(encoding="utf-8").splitlines():
        if found := re.match(r"#   (t\d_\w+) \(.*\): ([\d.]+), (\w+) [\d.]+, .*, ([\d.]+)$", line):
            truth[found.group(1)] = (float(found.group(2)), found.group(3), float(found.group(4)))
    assert len(truth) == 4
    covered, estimates = {False: 0, True: 0}, []
    for estimate_yield in (False, True):
        for name, (cut, formula, _) in truth.items():
            lab = pd.read_csv(DATA, comment="#")
            lab = lab[lab["experiment"] == name]
            found = tromplab.read_experiments(lab, estimate_yield=estimate_yield)
            fits = tromplab.fit_experiments(found, formulas=[formula], ci=0.95).fits_table()
            covered[estimate_yield] += bool(fits["d_cut_low"].iloc[0] <= cut <= fits["d_cut_high"].iloc[0])
            if estimate_yield:
                estimates.append(round(found.balances[0].fine_yield, 4))
    assert covered == {False: 3, True: 2}
    assert estimates == [0.5736, 0.4672, 0.5636, 0.6441]
    page = " ".join((ROOT / "docs" / "uncertainty.md").read_text(encoding="utf-8").split())
    assert "cover the true cut in 3 of 4 tests with the weighed yields and 2 of 4 with the estimated ones" in page
