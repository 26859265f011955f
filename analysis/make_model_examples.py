"""Generate the bundled example inputs of the process-model commands from published parameters.

Writes into ``datasets/`` (or ``--outdir``):

* ``sieve_identify_residues_example.csv`` for ``tromplab sieve identify``: residues of the
  kinetics paper's two fractions (2.5 x 1.5 mm: Vk = 0.148, sigma = 0.051 m/s; 2.0 x 1.5 mm:
  Vk = 0.185, sigma = 0.069 m/s) on its sieve (round holes D = 2 mm, cells 3.2 x 3.2 mm,
  length L = 1.6 m) at six relative-speed amplitudes, computed without noise as
  ``gamma = exp(-P_g P_v L / (2a))``;
* ``layer_extraction_example.csv`` for ``tromplab layer fit``: extraction of the layer
  model with the layer paper's parameters (d = 0.005, v0 = 0.026, vf0 = 0.21; 4 cells at
  C0 = 0.5, nonlinear, no locking; steps of 0.2 s) every 25 steps up to 300, plus normal
  noise of standard deviation 0.005 (seed 1);
* ``pulp_screen_productivity_example.csv`` for ``tromplab pulp fit``: productivity of the
  pulp screen with the spec's illustrative values (beta = 2, r = 2, lambda = 3, s = 0.5,
  phi = 0.0025, tau = 2, t1 = 0.01 s, F = 1 m^2, k0 = 0.2, c = 10 kg/m^3) on a grid of
  applied pressure drops and pulsation frequencies, times lognormal noise of 2 % (seed 2).

Usage: ``python analysis/make_model_examples.py [--outdir datasets]``
"""

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from tromplab.classifiers import sieve
from tromplab.classifiers.layer import LayerModel
from tromplab.classifiers.pulp import PulpScreen

ROOT = Path(__file__).resolve().parent.parent
REGENERATE = "Regenerate with: python analysis/make_model_examples.py"

SIEVE_LENGTH, CELL_PITCH, HOLE, HALF_CELL = 1.6, 0.0032, 2.0, 1.6  # m, m, mm, mm
SIEVE_FRACTIONS = {"2.5x1.5": (2.5, 1.5, 0.148, 0.051), "2.0x1.5": (2.0, 1.5, 0.185, 0.069)}  # l, d [mm]; Vk, sigma [m/s]
SIEVE_SPEEDS = (0.16, 0.20, 0.24, 0.28, 0.32, 0.36)  # relative-speed amplitudes Va [m/s]
LAYER = {"diffusion": 0.005, "segregation": 0.026, "passage": 0.21}
LAYER_CELLS, LAYER_C0, LAYER_STEP_SECONDS = 4, 0.5, 0.2
PULP = PulpScreen(phi=0.0025)
PULP_APPLIED = (0.25, 0.5, 1.0, 2.0)  # applied pressure drop H'
PULP_FREQUENCIES = (5.0, 10.0, 20.0)  # pulsations per second N


def sieve_residues() -> pd.DataFrame:
    rows = []
    for fraction, (length, width, v_k, sigma) in SIEVE_FRACTIONS.items():
        pg = sieve.geometric_probability(HOLE, length, width, HALF_CELL)
        speeds = np.array(SIEVE_SPEEDS)
        residues = sieve.residue_share(pg * sieve.velocity_probability(speeds, v_k, sigma), SIEVE_LENGTH, CELL_PITCH)
        for speed, residue in zip(speeds, residues):
            rows.append(
                {
                    "sieve": 1,
                    "fraction": fraction,
                    "relative_speed": speed,
                    "residue": float(f"{residue:.10g}"),
                    "sieve_length": SIEVE_LENGTH,
                    "cell_pitch": CELL_PITCH,
                    "hole_diameter": HOLE,
                    "length": length,
                    "width": width,
                    "half_cell_width": HALF_CELL,
                }
            )
    return pd.DataFrame(rows)


def layer_extraction() -> pd.DataFrame:
    run = LayerModel(**LAYER).simulate([LAYER_C0] * LAYER_CELLS, 300)
    steps = np.arange(25, 301, 25)
    noisy = run.extraction[steps - 1] + np.random.default_rng(1).normal(0.0, 0.005, steps.size)
    return pd.DataFrame({"step": steps, "time": np.round(steps * LAYER_STEP_SECONDS, 6), "extraction": np.round(noisy, 4)})


def pulp_productivity() -> pd.DataFrame:
    applied, frequency = (grid.ravel() for grid in np.meshgrid(PULP_APPLIED, PULP_FREQUENCIES, indexing="ij"))
    noise = np.exp(np.random.default_rng(2).normal(0.0, 0.02, applied.size))
    productivity = PULP.productivity(applied, frequency) * noise
    return pd.DataFrame({"applied_pressure": applied, "frequency": frequency, "productivity": np.round(productivity, 4)})


HEADERS = {
    "sieve_identify_residues_example.csv": f"""\
# Residues of two fractions on one sieve at six relative-speed amplitudes, for `tromplab sieve identify`.
# Generated (no noise) from the kinetics paper's published velocity laws: fraction 2.5x1.5 mm Vk = 0.148,
#   sigma = 0.051 m/s; fraction 2.0x1.5 mm Vk = 0.185, sigma = 0.069 m/s; sieve with round holes D = 2 mm,
#   cells 3.2 x 3.2 mm (cell_pitch 2a = 0.0032 m, half_cell_width b = 1.6 mm), length L = 1.6 m.
# residue = exp(-P_g P_v L / (2a)), P_v one-sided; P_g computed from the geometry columns (mm).
# Units: relative_speed m/s; sieve_length, cell_pitch m; hole_diameter, length, width, half_cell_width mm.
# {REGENERATE}
""",
    "layer_extraction_example.csv": f"""\
# Extraction of fines through a vibrating sieve against steps, for `tromplab layer fit`.
# Generated from the layer paper's parameters d = 0.005, v0 = 0.026, vf0 = 0.21 (nonlinear model, 4 cells,
#   initial concentration 0.5 in each, no locking; the paper states m = 4 and 50 %), one step = 0.2 s,
#   plus normal noise of standard deviation 0.005 (seed 1), rounded to 4 decimals.
# Units: step (count), time s, extraction 0..1 (share of the initial fines that passed).
# {REGENERATE}
""",
    "pulp_screen_productivity_example.csv": f"""\
# Productivity of a pulp pressure screen against applied pressure drop and pulsation frequency, for
#   `tromplab pulp fit`.
# Generated from the model Q = F k0 N c / alpha exp(-alpha a t1) (1 - exp(-alpha a / N)),
#   alpha = beta H^r, a = lambda H^s, H = H' + phi N^tau, with the illustrative values beta = 2, r = 2,
#   lambda = 3, s = 0.5, phi = 0.0025, tau = 2, t1 = 0.01 s, F = 1 m^2, k0 = 0.2, c = 10 kg/m^3
#   (relations (10)-(12) of the paper are lost in its print: see docs/errata.md), times lognormal
#   noise of 2 % (seed 2), rounded to 4 decimals.
# Units: applied_pressure H' (model units of beta and lambda), frequency 1/s, productivity Q (kg/s with the SI inputs above).
# {REGENERATE}
""",
}

BUILDERS = {
    "sieve_identify_residues_example.csv": sieve_residues,
    "layer_extraction_example.csv": layer_extraction,
    "pulp_screen_productivity_example.csv": pulp_productivity,
}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--outdir", type=Path, default=ROOT / "datasets", help="folder to write into (default: datasets)")
    args = parser.parse_args(argv)
    args.outdir.mkdir(parents=True, exist_ok=True)
    for name, build in BUILDERS.items():
        path = args.outdir / name
        with open(path, "w", newline="") as handle:
            handle.write(HEADERS[name])
            build().to_csv(handle, index=False, lineterminator="\n")
        print(f"Wrote {path}")


if __name__ == "__main__":
    main()
