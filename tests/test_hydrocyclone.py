"""Hydrocyclones: ``--water-recovery`` / ``water_recovery=``: the Kelsall-
corrected partition and the fitted bypass compared with the measured water split."""

import numpy as np
import pandas as pd
import pytest

import tromplab
from tromplab.cli import main
from tromplab.errors import OptionError
from tromplab.loading.kelsall import kelsall_corrected
from tromplab.loading.lab import LabOptions, read_lab
from tromplab.loading.points import TrompPoints
from tromplab.output.views import partition_view
from tromplab.statistics.hydrocyclone import bypass_against_water_recovery
from tromplab.workbench import fit_experiments

from .conftest import LAB_CLASS_HEADER, LAB_CLASS_ROWS, write

SIZES = np.geomspace(5.0, 200.0, 12)


def _cyclone(seed: int, bypass: float, formula: str = "plitt_bypass", shape: float = 2.5) -> TrompPoints:
    """Generated hydrocyclone points: a share ``bypass`` of every size short-circuits to the
    underflow with the water (noise 0.01, not clipped so the noise stays unbiased)."""
    rng = np.random.default_rng(seed)
    phi = tromplab.get_formula(formula)(SIZES, 40.0, shape, bypass=bypass) + rng.normal(0, 0.01, SIZES.size)
    return TrompPoints(f"cyclone-{seed}", SIZES, phi)


def test_kelsall_correction_is_the_corrected_partition_to_the_underflow():
    partition_fine = np.array([0.7, 0.5, 0.2, 0.0])
    water_recovery = 0.3
    coarse = 1.0 - partition_fine
    corrected_coarse = (coarse - water_recovery) / (1.0 - water_recovery)  # Kelsall (1953)
    np.testing.assert_allclose(kelsall_corrected(partition_fine, water_recovery), 1.0 - corrected_coarse)
    np.testing.assert_allclose(kelsall_corrected(partition_fine, 0.0), partition_fine)  # no water, no correction


@pytest.mark.parametrize("formula, shape", [("plitt_bypass", 2.5), ("lognormal_bypass", 0.5)])
def test_fitted_bypass_agrees_with_the_water_recovery_that_made_the_data(formula, shape):
    water_recovery = 0.3
    experiments = [_cyclone(seed, water_recovery, formula, shape) for seed in range(8)]
    bench = fit_experiments(experiments, formulas=["plitt", formula], water_recovery=water_recovery)
    fits = bench.fits_table()
    assert (fits["water_recovery"] == water_recovery).all()
    extended = fits[fits["formula"] == formula]
    assert extended["success"].all()
    assert np.abs(extended["bypass"] - water_recovery).max() < 0.03
    assert abs(extended["bypass"].mean() - water_recovery) < 0.01
    agrees = extended["water_recovery_check"].str.startswith("agrees").sum()
    assert agrees >= 6, extended["water_recovery_check"].tolist()  # 95 % intervals: about 7.6 of 8
    assert (fits.loc[fits["formula"] == "plitt", "water_recovery_check"] == "").all()  # no bypass to compare


def test_a_bypass_far_from_the_water_recovery_is_said_to_differ():
    fit = tromplab.fit_formula(_cyclone(1, 0.3), "plitt_bypass")
    check = bypass_against_water_recovery([fit], 0.15).loc[0, "water_recovery_check"]
    assert check.startswith("differs") and "above the water recovery 0.150" in check


def test_lab_points_carry_the_corrected_partition_in_both_views(tmp_path):
    lab = write(tmp_path, LAB_CLASS_HEADER + "\n".join(LAB_CLASS_ROWS), "lab.csv")
    balance = read_lab(lab, water_recovery=0.2)[0]
    table = balance.points_table()
    np.testing.assert_allclose(table["partition_fine_corrected"], table["partition_fine"] / 0.8)
    coarse = partition_view(table, "coarse")
    np.testing.assert_allclose(coarse["partition_coarse_corrected"], (coarse["partition_coarse"] - 0.2) / 0.8)
    assert "partition_fine_corrected" not in read_lab(lab)[0].points_table().columns


@pytest.mark.slow
def test_cli_fit_and_points_report_the_water_recovery(tmp_path, capsys):
    points = tmp_path / "cyclone.csv"
    pd.concat(
        [pd.DataFrame({"experiment": p.experiment, "size": p.size, "partition_fine": p.partition_fine}) for p in
         (_cyclone(0, 0.3), _cyclone(1, 0.3))]
    ).to_csv(points, index=False)  # fmt: skip
    out = tmp_path / "out"
    assert main(["fit", str(points), "-o", str(out), "--formulas", "plitt,plitt_bypass", "--water-recovery", "0.3",
                 "--no-figures"]) == 0  # fmt: skip
    console = capsys.readouterr().out
    assert "Fitted bypass against the water recovery 0.3" in console
    assert "cyclone-0, plitt_bypass: agrees: fitted bypass" in console
    fits = pd.read_csv(out / "fits.csv", keep_default_na=False)
    assert (fits["water_recovery"] == 0.3).all()
    assert fits.loc[fits["formula"] == "plitt_bypass", "water_recovery_check"].str.startswith("agrees").all()

    assert main(["fit", str(points), "-o", str(tmp_path / "nine"), "--formulas", "plitt", "--water-recovery", "0.3",
                 "--no-figures"]) == 0  # fmt: skip
    assert "no curve with bypass was fitted" in capsys.readouterr().out
    report = tmp_path / "report.html"
    assert main(["report", str(points), "-o", str(report), "--formulas", "plitt,plitt_bypass", "--water-recovery", "0.3"]) == 0
    assert "water recovery: plitt_bypass: agrees: fitted bypass" in report.read_text()

    lab = write(tmp_path, LAB_CLASS_HEADER + "\n".join(LAB_CLASS_ROWS), "lab.csv")
    written = tmp_path / "points.csv"
    assert main(["points", str(lab), "-o", str(written), "--water-recovery", "0.25", "--partition-to", "coarse"]) == 0
    table = pd.read_csv(written)
    np.testing.assert_allclose(table["partition_coarse_corrected"], (table["partition_coarse"] - 0.25) / 0.75)


BAD_VALUES = ["1", "-0.1", "nan"]


@pytest.mark.parametrize("bad", BAD_VALUES)
@pytest.mark.parametrize("command", ["fit", "report", "points"])
def test_a_bad_water_recovery_is_refused_on_the_command_line(tmp_path, capsys, command, bad):
    lab = write(tmp_path, LAB_CLASS_HEADER + "\n".join(LAB_CLASS_ROWS), "lab.csv")
    output = ["-o", str(tmp_path / ("out.csv" if command == "points" else "out.html" if command == "report" else "out"))]
    assert main([command, str(lab), *output, f"--water-recovery={bad}"]) == 2
    error = capsys.readouterr().err
    assert "--water-recovery" in error
    expected = "must lie in [0, 1)" if bad != "nan" else "takes a finite number"
    assert expected in error
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("bad", BAD_VALUES)
def test_a_bad_water_recovery_is_refused_in_python_with_the_same_words(tmp_path, bad, capsys):
    assert main(["points", "lab.csv", "-o", str(tmp_path / "p.csv"), f"--water-recovery={bad}"]) == 2
    cli_reason = (
        capsys.readouterr().err.strip().splitlines()[0].split("--water-recovery: ")[-1]
    )  # the line before the pointer to -h
    for call in (
        lambda: LabOptions(water_recovery=float(bad)),
        lambda: fit_experiments([_cyclone(0, 0.3)], formulas=["plitt"], water_recovery=float(bad)),
        lambda: kelsall_corrected(np.array([0.5]), float(bad)),
    ):
        with pytest.raises(OptionError) as error:
            call()
        assert error.value.option == "water_recovery"
        assert error.value.reason.split(", got")[0] == cli_reason.split(", got")[0]
