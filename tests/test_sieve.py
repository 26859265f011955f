"""Sieve classifiers: probabilities, kinetics, identification, multi-deck random walk."""

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose
from scipy import integrate, stats

from tromplab.classifiers import sieve
from tromplab.cli import main

from .conftest import reference

PUBLISHED = reference("sieve_published.csv").set_index("quantity")
SIEVE_LENGTH, CELL_PITCH = 1.6, 0.0032  # m: L and 2a of the kinetics paper's example
RHO, GAP, WIDTH = 1150.0, 0.004, 1.0  # kg/m3, m, m
LAMBDA_1, LAMBDA_2 = 1.31e-3, 0.127  # printed kinetic coefficients, 1/s


def published(name):
    row = PUBLISHED.loc[name]
    return row.computed, row.atol


def test_geometric_probability_published_example():
    computed, atol = published("P_g example (D 2 mm; cell 3.2 x 3.2; d/l 0.5; l 2.2 mm)")
    value = sieve.geometric_probability(2.0, 2.2, 1.1, 1.6)
    assert_allclose(value, computed, atol=atol)
    assert abs(value - 0.150) < 0.0015  # printed to three digits


@pytest.mark.parametrize("length, width", [(2.2, 1.1), (2.5, 1.5), (2.0, 1.5), (1.5, 0.5), (1.0, 0.9), (1.9, 0.3)])
def test_closed_form_and_quadrature_agree(length, width):
    assert sieve.closed_form_valid(2.0, length, width, 1.6)
    closed = sieve.geometric_probability(2.0, length, width, 1.6, method="closed")
    assert_allclose(closed, sieve.geometric_probability(2.0, length, width, 1.6, method="quadrature"), rtol=1e-9)


def test_closed_form_refused_outside_its_range_and_quadrature_used():
    assert not sieve.closed_form_valid(2.0, 3.0, 1.5, 1.6)  # k > 1: the particle does not fit at every angle
    with pytest.raises(ValueError, match="closed form needs"):
        sieve.geometric_probability(2.0, 3.0, 1.5, 1.6, method="closed")
    assert 0 <= sieve.geometric_probability(2.0, 3.0, 1.5, 1.6) < sieve.geometric_probability(2.0, 2.5, 1.5, 1.6)


def test_figure_3_family_falls_as_particles_grow_and_fatten():
    curves = sieve.geometric_probability_curves(2.0, 1.6, [0.25, 0.5, 0.75], np.linspace(0.8, 2.0, 7))
    for _, group in curves.groupby("shape_factor"):
        assert np.all(np.diff(group["P_g"].to_numpy()) > 0)  # larger D/l (smaller particle) passes more easily
    at_one = curves[np.isclose(curves["D_over_l"], 1.2)].sort_values("shape_factor")["P_g"].to_numpy()
    assert np.all(np.diff(at_one) < 0)  # fatter particles pass less often


@pytest.mark.parametrize(
    "name, vk, sigma",
    [
        ("P_v fraction 1 (Va 0.287; Vk 0.148; sigma 0.051)", 0.148, 0.051),
        ("P_v fraction 2 (Va 0.287; Vk 0.185; sigma 0.069)", 0.185, 0.069),
    ],
)
def test_velocity_probabilities_at_the_compromise(name, vk, sigma):
    computed, atol = published(name)
    assert_allclose(sieve.velocity_probability(0.287, vk, sigma), computed, atol=atol)


def test_two_sided_velocity_probability_is_one_at_rest_and_falls():
    speeds = np.linspace(0, 1, 50)
    p = sieve.velocity_probability_two_sided(speeds, 0.2, 0.05)
    assert p[0] == pytest.approx(1.0) and np.all(np.diff(p) <= 0)
    assert_allclose(p, 2 - stats.norm.cdf((speeds - 0.2) / 0.05) - stats.norm.cdf(0.2 / 0.05))


def test_compromise_check_with_the_corrected_mean_speed():
    """gamma = exp(-lambda L / V): the mean speed that puts gamma_1^2 at the 8 % purity limit is
    about 0.080 m/s and gives gamma_1^1 = 0.974 and E = 89.64 % (the printed 2.8e-2 m/s does not)."""
    speed = SIEVE_LENGTH * LAMBDA_2 / -np.log(0.08)
    gamma_1 = np.exp(-LAMBDA_1 * SIEVE_LENGTH / speed)
    assert_allclose(speed, 0.0805, atol=5e-4)
    assert_allclose([gamma_1, sieve.sieve_efficiency(gamma_1, 0.08)], [0.974, 89.64], atol=0.01)  # 89.634 at exactly 8 %
    assert abs(gamma_1 - 0.974) < 5e-4
    assert_allclose(sieve.capacity(RHO, GAP, WIDTH, speed), 1332, atol=1)  # printed 1340


def test_printed_mean_speed_is_inconsistent():
    speed = 2.8e-2
    gamma_1, gamma_2 = (np.exp(-lam * SIEVE_LENGTH / speed) for lam in (LAMBDA_1, LAMBDA_2))
    assert_allclose(sieve.sieve_efficiency(gamma_1, gamma_2), 92.7, atol=0.05)  # printed 89.64
    assert_allclose(sieve.capacity(RHO, GAP, WIDTH, speed), 463.7, atol=0.1)  # printed 1340


def test_compromise_check_built_up_from_the_probabilities():
    probabilities = []
    for (length, width), (vk, sigma) in zip([(2.5, 1.5), (2.0, 1.5)], [(0.148, 0.051), (0.185, 0.069)]):
        probabilities.append(sieve.geometric_probability(2.0, length, width, 1.6) * sieve.velocity_probability(0.287, vk, sigma))
    gamma_1, gamma_2 = sieve.residue_share(np.array(probabilities), SIEVE_LENGTH, CELL_PITCH)
    assert_allclose([gamma_1, gamma_2, sieve.sieve_efficiency(gamma_1, gamma_2)], [0.974, 0.088, 88.8], atol=0.05)
    assert abs(gamma_1 - 0.974) < 1e-3 and abs(gamma_2 - 0.088) < 1e-3
    # at the corrected speed the built-up coefficient is 1.35e-3 1/s against the printed 1.31e-3
    assert_allclose(sieve.kinetic_coefficient(probabilities[0], 0.0805, CELL_PITCH), LAMBDA_1, rtol=0.03)


# --- identification ---------------------------------------------------------------------
SPEEDS = np.array([0.18, 0.22, 0.26, 0.30, 0.34, 0.38])
PG = 0.15


def residues_for(v_k, sigma, two_sided=False, noise=0.0, seed=0):
    law = sieve.velocity_probability_two_sided if two_sided else sieve.velocity_probability
    gamma = sieve.residue_share(PG * law(SPEEDS, v_k, sigma), SIEVE_LENGTH, CELL_PITCH)
    return gamma * np.exp(np.random.default_rng(seed).normal(0, noise, gamma.size))


def identify(residues, two_sided=False, speeds=SPEEDS):
    return sieve.identify_velocity_law(
        speeds, residues, geometric_prob=PG, sieve_length=SIEVE_LENGTH, cell_pitch=CELL_PITCH, two_sided=two_sided
    )


def test_one_sided_identification_recovers_the_law_and_matches_the_linear_solution():
    law = identify(residues_for(0.25, 0.06))
    assert_allclose([law.v_k, law.sigma], [0.25, 0.06], rtol=1e-8)
    assert_allclose([law.linear_v_k, law.linear_sigma], [0.25, 0.06], rtol=1e-8)


def test_one_sided_identification_with_noise_agrees_with_the_closed_form():
    law = identify(residues_for(0.25, 0.06, noise=0.02, seed=3))
    assert_allclose([law.v_k, law.sigma], [law.linear_v_k, law.linear_sigma], rtol=1e-6)
    assert_allclose([law.v_k, law.sigma], [0.25, 0.06], rtol=0.1)
    low, high = law.fit.confidence_intervals(0.95)["v_k"]
    assert low < law.v_k < high and np.isfinite(law.stderr["sigma"])


def test_two_sided_identification_recovers_the_law():
    law = identify(residues_for(0.25, 0.06, two_sided=True), two_sided=True)
    assert law.fit.success
    assert_allclose([law.v_k, law.sigma], [0.25, 0.06], rtol=1e-6)
    noisy = identify(residues_for(0.25, 0.06, two_sided=True, noise=0.02, seed=5), two_sided=True)
    assert_allclose([noisy.v_k, noisy.sigma], [0.25, 0.06], rtol=0.15)


@pytest.mark.parametrize(
    "residues, speeds, message",
    [
        ([0.5, 1.0, 0.4, 0.3], SPEEDS[:4], "residue 1 of regime 2 must lie strictly between 0 and 1"),
        ([0.5, 0.0, 0.4, 0.3], SPEEDS[:4], "residue 0 of regime 2"),
        ([0.5, 1e-40, 0.4, 0.3], SPEEDS[:4], "regime 2: sieving probability / P_g"),
        ([0.5], SPEEDS[:1], "at least two speed regimes"),
        ([0.5, 0.4, 0.3], SPEEDS[:4], "4 speeds but 3 residues"),
    ],
)
def test_identification_bad_input(residues, speeds, message):
    with pytest.raises(ValueError, match=message):
        identify(np.array(residues), speeds=speeds)


def test_dependence_predicts_fractions_without_residues():
    holes = np.full(4, 2.0)
    lengths = np.array([2.0, 2.25, 2.5, 2.75])
    v_k = 0.05 + 0.06 * lengths / holes
    dependence = sieve.fit_dependence(holes, lengths, v_k)
    assert_allclose(dependence.predict(2.0, 1.5), 0.05 + 0.06 * 0.75, rtol=1e-8)
    power = sieve.fit_dependence(holes, lengths, 0.1 * (lengths / holes) ** 1.5, form="a * (l / D) ** b")
    assert_allclose([power.fit.values["a"], power.fit.values["b"]], [0.1, 1.5], rtol=1e-6)

    def linear_in_l(D, l, c0, c1):
        return c0 + c1 * l

    assert_allclose(sieve.fit_dependence(holes, lengths, v_k, form=linear_in_l).predict(2.0, 1.0), 0.08, rtol=1e-8)
    with pytest.raises(ValueError, match="cannot determine"):
        sieve.fit_dependence(holes[:2], lengths[:2], v_k[:2])


# --- multi-deck random walk -------------------------------------------------------------
def test_pascal_closed_form_solves_the_difference_equations():
    p, decks, cells = 0.3, 6, 40
    table = np.zeros((decks + 1, cells + 1))
    table[0, 1] = 1.0
    for i in range(1, decks + 1):
        for j in range(1, cells + 1):
            table[i, j] = p * table[i - 1, j] + (1 - p) * table[i, j - 1]
    assert_allclose(table[decks, 1:], sieve.cell_probability(decks, np.arange(1, cells + 1), p), atol=1e-15)
    mean, variance = sieve.cell_moments(decks, p)
    cells_all = np.arange(1, 2000)
    pmf = sieve.cell_probability(decks, cells_all, p)
    assert_allclose([np.sum(cells_all * pmf), np.sum((cells_all - mean) ** 2 * pmf)], [mean, variance], rtol=1e-10)


def test_distance_distribution_solves_the_ode_system():
    """F_j' = -C x F_j + C x F_{j-1} (j >= 1), F_0' = -C x F_0, F_0(0) = 1: F_m = 1 - sum_{j<m} F_j."""
    decks, c = 5, 14.0

    def rhs(x, f):
        shifted = np.concatenate(([0.0], f[:-1]))
        return c * x * (shifted - f)

    x = np.linspace(0, 1.6, 50)
    solution = integrate.solve_ivp(rhs, (0, 1.6), np.eye(decks)[0], t_eval=x, rtol=1e-11, atol=1e-13)
    assert_allclose(1 - solution.y.sum(axis=0), sieve.distance_cdf(x, decks, c), atol=1e-9)
    fine = np.linspace(0.2, 1.6, 4001)
    density = np.gradient(sieve.distance_cdf(fine, decks, c), fine)
    assert_allclose(sieve.distance_pdf(fine[1:-1], decks, c), density[1:-1], rtol=5e-5)


def test_exact_moments_and_the_printed_approximations():
    mean, variance = sieve.distance_moments(12, 14.22)
    x = np.linspace(0, 5, 20001)
    pdf = sieve.distance_pdf(x, 12, 14.22)
    assert_allclose([np.trapezoid(x * pdf, x), np.trapezoid((x - mean) ** 2 * pdf, x)], [mean, variance], rtol=1e-6)
    printed_mean, printed_var = sieve.distance_moments_printed(12, 14.22)
    # random-walk paper (003), moments (11) at m = 12 (docs/errata.md): the printed mean is 0.011 %
    # below the exact one, the printed variance 1.07 % above; to half a unit of the last digit given
    assert_allclose(100 * (printed_mean / mean - 1), -0.011, atol=5e-4)
    assert_allclose(100 * (printed_var / variance - 1), 1.07, atol=5e-3)
    assert_allclose(sieve.distance_moments_printed(12, 1.0)[1] / sieve.distance_moments(12, 1.0)[1], printed_var / variance)


def test_bin_design_published_example():
    exact = sieve.design_bin(12, 1.6, 0.9)
    normal = sieve.design_bin(12, 1.6, 0.9, method="normal")
    for name, value in [
        ("C (m 12; L 1.6 m; g* 0.9)", exact.c),
        ("x1 exact (m 12; L 1.6 m; g* 0.9)", exact.x1),
        ("x1 normal approximation", normal.x1),
    ]:
        computed, atol = published(name)
        assert_allclose(value, computed, atol=atol)
    assert abs(exact.x1 - 0.98) < 0.01 and abs(normal.x1 - 0.98) < 0.005
    assert_allclose(exact.recovery, 0.9, atol=1e-12)
    assert_allclose(sieve.bin_recovery(exact.x1, exact.x2, 12, exact.c), 0.9, atol=1e-12)


def test_printed_efficiency_and_capacity_of_the_random_walk_paper_are_not_reproduced():
    e_computed, e_atol = published("E bin (g 0.9; purity S 10.4 %)")
    q_computed, q_atol = published("Q (rho 1150; h 3 mm; B 1 m; V 0.1185 m/s) kg/h")
    assert_allclose(sieve.bin_efficiency(0.9, 0.104), e_computed, atol=e_atol)
    assert_allclose(sieve.capacity(1150, 0.003, 1.0, 0.1185), q_computed, atol=q_atol)
    assert abs(e_computed - 81.5) > 0.5 and abs(q_computed - 1490) > 10


@pytest.mark.parametrize("lost_side", ["before", "beyond"])
def test_identify_c_round_trip_and_passage_probability(lost_side):
    design = sieve.design_bin(12, 1.6, 0.9)
    truths = np.array([8.0, 11.0]) if lost_side == "beyond" else np.array([20.0, 30.0])
    shares = [sieve.bin_recovery(design.x1, design.x2, 12, c) for c in truths]
    assert_allclose(sieve.identify_c(design.x1, design.x2, 12, shares, lost_side=lost_side), truths, rtol=1e-8)
    p = sieve.passage_probability_from_c(14.22, 12, 0.0035)
    assert_allclose(p, 12 * 0.0035 / sieve.distance_moments(12, 14.22)[0])


def test_identify_cli_continues_past_a_failing_group(tmp_path, capsys):
    rows = []
    for fraction, (v_k, sigma) in {"coarse": (0.25, 0.06), "fine": (0.2, 0.05)}.items():
        for speed, residue in zip(SPEEDS, residues_for(v_k, sigma)):
            rows.append(
                {
                    "sieve": 1,
                    "fraction": fraction,
                    "relative_speed": speed,
                    "residue": residue,
                    "sieve_length": SIEVE_LENGTH,
                    "cell_pitch": CELL_PITCH,
                    "P_g": PG,
                }
            )
    rows.append({**rows[-1], "fraction": "broken", "residue": 0.9})  # one regime: two parameters not identifiable
    path = tmp_path / "residues.csv"
    pd.DataFrame(rows).to_csv(path, index=False)
    output = tmp_path / "laws.csv"
    assert main(["sieve", "identify", str(path), "-o", str(output)]) == 3  # written, one group failed: partial
    laws = pd.read_csv(output).set_index("fraction")
    assert_allclose(laws.loc["coarse", ["v_k", "sigma"]].astype(float), [0.25, 0.06], rtol=1e-6)
    assert not laws.loc["broken", "success"] and "at least two speed regimes" in laws.loc["broken", "message"]
    assert laws.loc["coarse", "v_k_low"] <= 0.25 <= laws.loc["coarse", "v_k_high"]
    assert "not identified: sieve 1, fraction broken" in capsys.readouterr().out


def _residue_table(tmp_path, **change):
    """Residues of one fraction at the six speeds; ``change`` = {column: (row, value)}."""
    frame = pd.DataFrame(
        {
            "sieve": 1,
            "fraction": "coarse",
            "relative_speed": SPEEDS,
            "residue": residues_for(0.25, 0.06),
            "sieve_length": SIEVE_LENGTH,
            "cell_pitch": CELL_PITCH,
            "P_g": PG,
        }
    )
    for column, (row, value) in change.items():
        frame.loc[row, column] = value
    path = tmp_path / "residues.csv"
    frame.to_csv(path, index=False)
    return path


@pytest.mark.parametrize(
    "column, value, words",
    [
        ("residue", 1.3, "residue 1.3 must lie strictly between 0 and 1"),
        ("residue", 1.0, "residue 1 must lie strictly between 0 and 1"),
        ("residue", 0.0, "residue 0 must lie strictly between 0 and 1"),
        ("sieve_length", -1.6, r"sieve_length -1.6 must lie in \(0, 1e\+100\]"),
        ("cell_pitch", 0.0, r"cell_pitch 0 must lie in \(0, 1e\+100\]"),
        ("P_g", 1.2, r"P_g 1.2 must lie in \(0, 1\]"),
    ],
)
def test_identify_refuses_a_cell_outside_its_range_naming_file_row_and_column(tmp_path, column, value, words):
    """A residue of 1.3 gave a table with success False and exit 0; the Python API and
    the command now refuse the input as fit does (row 4 = the third data row)."""
    from tromplab.errors import InputError
    from tromplab.loading.tables import read_table

    path = _residue_table(tmp_path, **{column: (2, value)})
    with pytest.raises(InputError, match=rf"residues.csv, row 4, column '{column}': {words}") as raised:
        sieve.identify_from_table(read_table(path))
    assert (raised.value.row, raised.value.column) == (4, column)


def test_identify_command_refuses_a_residue_above_one_and_writes_nothing(tmp_path, capsys):
    path = _residue_table(tmp_path, residue=(2, 1.3))
    output = tmp_path / "laws.csv"
    assert main(["sieve", "identify", str(path), "-o", str(output)]) == 1
    error = capsys.readouterr().err
    assert "tromplab sieve identify: error:" in error
    assert "residues.csv, row 4, column 'residue': residue 1.3 must lie strictly between 0 and 1" in error
    assert not output.exists()
    assert main(["sieve", "identify", str(_residue_table(tmp_path)), "-o", str(output)]) == 0  # the same table, valid
    assert output.exists()


def test_pg_and_bin_commands(capsys):
    assert main(["sieve", "pg", "--hole", "2", "--length", "2.2", "--width", "1.1", "--cell-width", "3.2"]) == 0
    assert "P_g = 0.151140" in capsys.readouterr().out
    assert main(["sieve", "bin", "--decks", "12", "--length", "1.6", "--recovery", "0.9"]) == 0
    printed = capsys.readouterr().out
    assert "C = 14.2246 per L-unit², x1 = 0.9867 L-units" in printed and "x1 = 0.9808 L-units" in printed
    assert "C: the passage intensity coefficient" in printed and "L-unit: the unit --length was given in" in printed


def test_identification_from_bin_shares_round_trip():
    """Known (Vk, sigma): bin shares at five regimes are generated and identified back."""
    decks, pitch, pg, v_k, sigma = 12, 0.0035, 0.3, 0.3, 0.08
    design = sieve.design_bin(decks, 1.6, 0.9)
    c = np.array([4.0, 6.0, 8.0, 10.0, 12.0])  # all below the C of the largest bin share: material lost beyond x2
    ratio = np.array([sieve.passage_probability_from_c(value, decks, pitch) for value in c]) / pg
    z = stats.norm.ppf(2.0 - stats.norm.cdf(v_k / sigma) - ratio)  # invert the two-sided law for the speeds
    speeds = v_k + sigma * z
    shares = [sieve.bin_recovery(design.x1, design.x2, decks, value) for value in c]
    law = sieve.identify_from_bin_shares(
        speeds, shares, x1=design.x1, x2=design.x2, decks=decks, cell_pitch=pitch, geometric_prob=pg, lost_side="beyond"
    )
    assert_allclose([law.v_k, law.sigma], [v_k, sigma], rtol=1e-6)
    with pytest.raises(ValueError, match="cannot be reached"):
        sieve.identify_from_bin_shares(
            speeds, [0.99] * 5, x1=design.x1, x2=design.x2, decks=decks, cell_pitch=pitch, geometric_prob=pg, lost_side="beyond"
        )


def test_identify_table_computes_p_g_from_the_geometry(tmp_path):
    from tromplab.loading.tables import read_table

    pg = sieve.geometric_probability(2.0, 2.5, 1.5, 1.6)
    gamma = sieve.residue_share(pg * sieve.velocity_probability(SPEEDS, 0.148, 0.051), SIEVE_LENGTH, CELL_PITCH)
    frame = pd.DataFrame(
        {
            "sieve": 1,
            "fraction": "2.5x1.5",
            "relative_speed": SPEEDS,
            "residue": gamma,
            "sieve_length": SIEVE_LENGTH,
            "cell_pitch": CELL_PITCH,
            "hole_diameter": 2.0,
            "length": 2.5,
            "width": 1.5,
            "half_cell_width": 1.6,
        }
    )
    frame.to_csv(tmp_path / "geometry.csv", index=False)
    laws = sieve.identify_from_table(read_table(tmp_path / "geometry.csv"))
    assert_allclose(laws.loc[0, "P_g"], pg)
    assert_allclose(laws.loc[0, ["v_k", "sigma"]].astype(float), [0.148, 0.051], rtol=1e-6)
    frame.drop(columns=["width"]).to_csv(tmp_path / "missing.csv", index=False)
    from tromplab.errors import InputError

    with pytest.raises(InputError, match="give a 'P_g' column or the columns"):
        sieve.identify_from_table(read_table(tmp_path / "missing.csv"))
