"""Every command of tromplab run on the bundled data sets, for the test that its folder is the
one its Python function's ``save()`` writes and the one the code wrote before the commands took
one shape (``tests/test_command_functions.py``).

``OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 python tests/command_cases.py
--record tests/data/command_digests.json --scratch DIR`` runs every case through the command
line and records the SHA-256 of each text file it writes.  It was first run on the code before
the commands took one shape (main at 52a2c1d), and run again when later work changed outputs on
purpose (CHANGELOG: the circuit's deterministic Gauss-Newton solve and its ``warnings.csv``, the
plant's evaluation columns, the density intervals' shared profile search, the design
candidates' Cholesky solves in numpy instead of scipy.linalg (``design.csv`` of three circuit
cases, by 2e-13 relative at most), the plain density curves' profile limits closed by Newton's
method (``density fit with intervals`` only, within 3.2e-14 relative of before), and those of the
curves with limits in their smooth brackets (the same case, within 4.8e-13), whose numbers
agree with the earlier ones to 1e-9 relative; the codes of the quasi-binomial scale's notes in
that case's ``warnings.csv``, and the design reductions within the updates' rounding written
as none in ``design.csv`` of four circuit cases); from the repository's root, with relative data set
names, so that the digests do not depend on where the checkout lives.
Figures (PNG) are left out of the stored digests, as they depend on matplotlib's version; the
test compares them between the command line and the API, which run in the same environment.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: The bundled data sets as the cases name them: relative to the repository's root, where every
#: case runs (:func:`run_command`), so that no file records where the checkout lives (the
#: plant's devices name their source file and row).
DATASETS = Path("datasets")

#: A two-product float-sink test with the feed's ash by density fraction (the hand case of
#: tests/test_plant_evaluate.py): -1.4, 1.4-1.6 and +1.6 at 50, 25 and 25 % of the feed, 10, 30
#: and 70 % ash, partitions to the sinks 0.1, 0.5 and 0.9; no bundled data set is such a table.
FLOAT_SINK_TEST = (
    "test,density_lower,density_upper,feed_pct,floats_pct,sinks_pct,feed_ash_pct\n"
    "hand,,1.4,50,75,12.5,10\n"
    "hand,1.4,1.6,25,20.833333333333332,31.25,30\n"
    "hand,1.6,,25,4.166666666666667,56.25,70\n"
)

#: Each case: its name, the command line with ``{out}`` for the output folder (``{inputs}`` for
#: the folder of written inputs), and whether the command writes one file (``-o FILE``) into it.
CASES = {
    "fit lab table with intervals": ["fit", str(DATASETS / "double_deck_screen_decks_lab.csv"), "--size-unit", "mm",
                                     "--ci", "0.95", "-o", "{out}"],
    "fit lab table, extended, no figures": ["fit", str(DATASETS / "air_classifier_lab_synthetic.csv"), "--extended",
                                         "--no-figures", "-o", "{out}"],
    "density fit with intervals": ["density", "fit", str(DATASETS / "density_tracers_dmc_by_size_synthetic.csv"),
                                   "--ci", "0.95", "-o", "{out}"],
    "density fit plain, no figures": ["density", "fit", str(DATASETS / "density_tracers_dmc_by_size_synthetic.csv"),
                                      "--curves", "plain", "--figures", "none", "-o", "{out}"],
    "density predict": ["density", "predict", str(DATASETS / "density_washability_synthetic.csv"), "--rho50", "1.45",
                        "1.6", "--ep", "0.05", "-o", "{out}/prediction.csv", "--table", "{out}/washability.csv"],
    "density predict target ash": ["density", "predict", str(DATASETS / "density_washability_synthetic.csv"),
                                   "--target-ash", "8", "12", "--ep", "0.04", "--curve", "logistic",
                                   "-o", "{out}/prediction.csv"],
    "circuit with fits": ["circuit", str(DATASETS / "circuit_example_flowsheet.csv"),
                          str(DATASETS / "circuit_example_survey.csv"), "--fit", "-o", "{out}"],
    "circuit excluded, no figures": ["circuit", str(DATASETS / "circuit_example_flowsheet.csv"),
                                     str(DATASETS / "circuit_example_survey.csv"), "--no-figures",
                                     "--exclude", "screen_feed:flow", "--weighting", "feed-share", "-o", "{out}"],
    "circuit design of a survey": ["circuit", "design", str(DATASETS / "circuit_example_flowsheet.csv"),
                                   str(DATASETS / "circuit_example_survey.csv"), "-o", "{out}"],
    "circuit design simulated": ["circuit", "design", str(DATASETS / "circuit_example_flowsheet.csv"), "-o", "{out}"],
    "trend": ["trend", str(DATASETS / "classifier_trend_surveys.csv"), "-o", "{out}"],
    "trend no figures": ["trend", str(DATASETS / "classifier_trend_surveys.csv"), "--alpha", "0.05", "--no-figures",
                         "-o", "{out}"],
    "plant predict": ["plant", "predict", str(DATASETS / "plant_washability_synthetic.csv"),
                      str(DATASETS / "plant_devices_synthetic.csv"), "--draws", "300", "--seed", "5", "-o", "{out}"],
    "plant optimize": ["plant", "optimize", str(DATASETS / "plant_washability_synthetic.csv"),
                       str(DATASETS / "plant_devices_synthetic.csv"), "--target-ash", "10", "--draws", "200",
                       "-o", "{out}"],
    "plant evaluate": ["plant", "evaluate", "{inputs}/float_sink_test.csv", "-o", "{out}"],
}  # fmt: skip


#: The BLAS threads of the recording and of the check: one, as the ``tromplab`` launcher sets
#: them (tromplab._launch); the circuit's last bits depend on the number.
ONE_BLAS_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def write_inputs(folder: Path) -> Path:
    """The inputs no bundled data set holds, written into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "float_sink_test.csv").write_text(FLOAT_SINK_TEST, encoding="utf-8")
    return folder


def command_line(name: str, out: Path, inputs: Path) -> list[str]:
    """The arguments of case ``name`` writing into ``out``."""
    return [arg.replace("{out}", str(out)).replace("{inputs}", str(inputs)) for arg in CASES[name]]


def run_command(name: str, out: Path, inputs: Path) -> int:
    """Run case ``name`` through the command line (its console swallowed); its exit code."""
    from tromplab.cli import main

    with contextlib.chdir(ROOT), contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main(command_line(name, out, inputs))


def digests(folder: Path, *, text_only: bool) -> dict[str, str]:
    """SHA-256 of every file under ``folder`` (PNG figures left out with ``text_only``)."""
    return {
        str(path.relative_to(folder)): hashlib.sha256(path.read_bytes()).hexdigest()
        for path in sorted(folder.rglob("*"))
        if path.is_file() and not (text_only and path.suffix == ".png")
    }


def record(target: Path, scratch: Path) -> None:
    """Run every case and write the digests of their text files to ``target``."""
    inputs = write_inputs(scratch / "inputs")
    recorded = {}
    for name in CASES:
        out = scratch / name.replace(" ", "_").replace(",", "")
        code = run_command(name, out, inputs)
        recorded[name] = {"exit": code, "files": digests(out, text_only=True)}
        print(f"{name}: exit {code}, {len(recorded[name]['files'])} text file(s)")
    target.write_text(json.dumps(recorded, indent=1, sort_keys=True) + "\n", encoding="utf-8")


def fresh_digests(name: str, scratch: Path) -> dict:
    """Case ``name`` run through the command line in a fresh interpreter, as it was recorded:
    its exit code and the digests of its text files.  The circuit's linear algebra moves in the
    last bit with the memory layout of a long-lived process (OpenBLAS's alignment), so the
    comparison with the recorded run is made from a process as fresh as the recording's."""
    import subprocess

    script = (
        "import json, sys; from pathlib import Path; sys.path.insert(0, sys.argv[1]); import command_cases as c; "
        "out, inputs = Path(sys.argv[3]) / 'out', c.write_inputs(Path(sys.argv[3]) / 'inputs'); "
        "code = c.run_command(sys.argv[2], out, inputs); "
        "print(json.dumps({'exit': code, 'files': c.digests(out, text_only=True) if out.exists() else {}}))"
    )
    done = subprocess.run([sys.executable, "-c", script, str(Path(__file__).parent), name, str(scratch)],
                          capture_output=True, text=True, check=True, env={**os.environ, **ONE_BLAS_THREAD})  # fmt: skip
    return json.loads(done.stdout.splitlines()[-1])


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", type=Path, required=True, help="JSON file of the digests")
    parser.add_argument("--scratch", type=Path, required=True, help="an empty folder for the runs")
    options = parser.parse_args()
    record(options.record, options.scratch)
    sys.exit(0)
