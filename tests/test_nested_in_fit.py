"""``fit --extended`` asks of each extended curve whether its extra term is needed (the nested
F test against the curve it extends), in fits.csv and on the console."""

import numpy as np
import pandas as pd

import tromplab
from tromplab.cli import main
from tromplab.statistics.compare import nested_f_test

SIZES = np.geomspace(5, 400, 12)


def _points(name: str, bypass: float, seed: int) -> tromplab.TrompPoints:
    rng = np.random.default_rng(seed)
    plitt = tromplab.get_formula("plitt_bypass")
    phi = plitt(SIZES, 60.0, 2.5, bypass=bypass) + rng.normal(0, 0.01, SIZES.size)
    return tromplab.TrompPoints(name, SIZES, np.clip(phi, 0, 1))


def test_the_nested_test_finds_a_real_bypass_and_no_phantom_one():
    bench = tromplab.fit_experiments([_points("with", 0.3, 1), _points("without", 0.0, 2)], extended=True)
    fits = bench.fits_table().set_index(["experiment", "formula"])
    assert fits.loc[("with", "plitt_bypass"), "nests"] == "plitt"
    assert fits.loc[("with", "plitt_bypass"), "nested_p"] < 1e-6
    assert fits.loc[("without", "plitt_bypass"), "nested_p"] > 0.05
    assert np.isnan(fits.loc[("with", "plitt"), "nested_p"])  # the nine nest nothing
    by_hand = nested_f_test(*(f for f in bench.fits_of("with") if f.formula.id in ("plitt", "plitt_bypass")))
    np.testing.assert_allclose(fits.loc[("with", "plitt_bypass"), ["nested_F", "nested_p"]], [by_hand.F, by_hand.p_value])


def test_the_command_writes_the_columns_and_says_it_in_words(tmp_path, capsys):
    path = tmp_path / "points.csv"
    frame = _points("with", 0.3, 1).to_frame()
    frame.to_csv(path, index=False)
    assert main(["fit", str(path), "-o", str(tmp_path / "out"), "--extended", "--figures", "none"]) == 0
    said = capsys.readouterr().out
    assert "with: plitt_bypass against plitt: F = " in said and said.split("plitt_bypass against plitt")[1].split("\n")[
        0
    ].endswith(": yes")
    assert {"nests", "nested_F", "nested_p"} <= set(pd.read_csv(tmp_path / "out" / "fits.csv").columns)
    assert main(["fit", str(path), "-o", str(tmp_path / "plain"), "--figures", "none"]) == 0
    assert "nested_p" not in pd.read_csv(tmp_path / "plain" / "fits.csv").columns  # without --extended nothing changes
