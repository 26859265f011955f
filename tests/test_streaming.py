"""A batch streamed to disk chunk by chunk (``fit_to_folder(stream=True)``, what ``tromplab fit``
does from ``STREAM_THRESHOLD`` experiments) writes the results folder of the in-memory path
byte for byte, for every configuration; its Workbench refits an experiment into the fits the
workers had; a run that fails leaves no folder and no scratch files."""

import filecmp
import os

import numpy as np
import pandas as pd
import pytest

from tromplab import TrompPoints
from tromplab._synthetic import synthetic
from tromplab.cli import fit as fit_command
from tromplab.cli import main
from tromplab.loading.lab import LabOptions, read_experiments
from tromplab.loading.tables import read_table
from tromplab.parallel import fanout as fanout_module
from tromplab.parallel import streaming as streaming_module
from tromplab.workbench import ExperimentsInPieces, FitsInMemory, FitsOnDisk, fit_to_folder
from tromplab.workbench import stream as stream_module

from .conftest import DATASETS

FORMULAS = "plitt,lognormal,shuvalov"


@pytest.fixture(autouse=True)
def _units_of_64(monkeypatch):
    """Units of work of at most 64 experiments: one worker makes as few as the largest unit
    allows, and the batches here are to be joined from several chunks on one worker too."""
    monkeypatch.setattr(fanout_module, "MAX_CHUNK_SIZE", 64)


def _batch(n=70, *, failures=True):
    """``n`` synthetic experiments (two chunks of 64 on one worker) and, with ``failures``, one with
    two points and a flat one, which the screen cannot judge (their rows end the fits table)."""
    data = [synthetic(seed, weighted=False) for seed in range(n)]
    if failures:
        data.insert(3, TrompPoints("two_points", [10.0, 40.0], [0.9, 0.2]))
        data.insert(40, TrompPoints("flat", [10.0, 20.0, 40.0], [0.5, 0.5, 0.5]))
    return data


def _same_folders(left, right) -> list[str]:
    names = sorted(p.name for p in left.iterdir())
    assert names == sorted(p.name for p in right.iterdir())
    assert "fits.csv" in names and "ranking.csv" in names and "averages.csv" in names
    return [name for name in names if not filecmp.cmp(left / name, right / name, shallow=False)]


CONFIGURATIONS = {
    "plain": {},
    "ci": {"ci": 0.9},
    "bootstrap": {"bootstrap": 20, "seed": 3},
    "extended": {"extended": True},
    "coarse": {"partition_to": "coarse", "ci": 0.9},
    "water recovery, aicc": {"water_recovery": 0.3, "rank_by": "aicc", "formulas": "plitt,plitt_bypass,lognormal"},
}


@pytest.mark.parametrize("jobs", [1, 2])
@pytest.mark.parametrize("configuration", list(CONFIGURATIONS))
@pytest.mark.slow
def test_a_streamed_batch_writes_the_folder_of_the_in_memory_path_byte_for_byte(tmp_path, configuration, jobs):
    options = {"formulas": FORMULAS, **CONFIGURATIONS[configuration], "jobs": jobs}
    data = _batch()
    kept, _ = fit_to_folder(data, tmp_path / "memory", stream=False, **options)
    streamed, written = fit_to_folder(data, tmp_path / "streamed", stream=True, **options)
    assert isinstance(streamed.store, FitsOnDisk) and isinstance(kept.store, FitsInMemory)
    assert "overview.png" in written and "failures.csv" in written
    assert _same_folders(tmp_path / "memory", tmp_path / "streamed") == []
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no scratch left
    pd.testing.assert_frame_equal(streamed.ranking_table(), kept.ranking_table())
    pd.testing.assert_frame_equal(streamed.failure_table(), kept.failure_table())
    assert streamed.experiments == kept.experiments and streamed.notes == kept.notes


@pytest.mark.slow
def test_a_streamed_workbench_refits_an_experiment_into_the_fits_the_workers_made(tmp_path):
    data = _batch()
    kept, _ = fit_to_folder(data, tmp_path / "memory", stream=False, formulas=FORMULAS, jobs=1, ci=0.9)
    streamed, _ = fit_to_folder(data, tmp_path / "streamed", stream=True, formulas=FORMULAS, jobs=1, ci=0.9)
    for experiment in ("s0", "s50", "s69"):  # the first, a middle and the last chunk
        for formula in FORMULAS.split(","):
            made, rebuilt = kept.fit(experiment, formula), streamed.fit(experiment, formula)
            assert _equal_rows(rebuilt, made)
            assert rebuilt.fit.ssr == made.fit.ssr
            assert rebuilt.fit.values == made.fit.values
            assert str(rebuilt.fit.stderr) == str(made.fit.stderr)  # nan compares unequal to itself
            assert rebuilt.warnings == made.warnings
        assert streamed.best_fit(experiment).formula.id == kept.best_fit(experiment).formula.id
        assert streamed.verdicts(experiment) == kept.verdicts(experiment)
        top = streamed.top_ranked(experiment).reset_index(drop=True)  # the row labels of one experiment's own table
        pd.testing.assert_frame_equal(top, kept.top_ranked(experiment).reset_index(drop=True))
    assert len(streamed.fits) == len(kept.fits) and streamed.n_successful == kept.n_successful
    assert [f.formula.id for f in streamed.fits[9:12]] == [f.formula.id for f in kept.fits[9:12]]
    with pytest.raises(KeyError, match="no fitted experiment"):
        streamed.fit("two_points", "plitt")
    # the tables of a streamed batch come from its folder: the values written, exactly
    read = streamed.fits_table()
    made = kept.fits_table()
    assert list(read.columns) == list(made.columns) and len(read) == len(made)
    np.testing.assert_array_equal(read["ssr"].to_numpy(), made["ssr"].to_numpy())
    head = streamed.fits_table(experiments=["s1", "s2"])
    pd.testing.assert_frame_equal(head.reset_index(drop=True), kept.fits_table(experiments=["s1", "s2"]).reset_index(drop=True))


def _equal_rows(left, right) -> bool:
    a, b = left.row(), right.row()
    return a.keys() == b.keys() and all(x == y or (x != x and y != y) for x, y in zip(a.values(), b.values()))


@pytest.mark.slow
def test_a_streamed_batch_writes_the_same_folder_on_one_worker_and_on_two(tmp_path):
    data = _batch()
    fit_to_folder(data, tmp_path / "one", stream=True, formulas=FORMULAS, jobs=1, bootstrap=10)
    fit_to_folder(data, tmp_path / "two", stream=True, formulas=FORMULAS, jobs=2, bootstrap=10)
    assert _same_folders(tmp_path / "one", tmp_path / "two") == []


@pytest.mark.slow
def test_workers_that_cannot_see_the_folder_send_their_files_back_with_the_same_result(tmp_path, monkeypatch):
    """Gather mode: a Dask cluster's workers on machines without the output folder."""
    data = _batch()
    fit_to_folder(data, tmp_path / "memory", stream=False, formulas=FORMULAS, jobs=2, ci=0.9)
    monkeypatch.setattr(stream_module, "_workers_see", lambda cluster, folder: False)
    fit_to_folder(data, tmp_path / "gathered", stream=True, formulas=FORMULAS, jobs=2, ci=0.9)
    assert _same_folders(tmp_path / "memory", tmp_path / "gathered") == []


@pytest.mark.slow
def test_a_failing_streamed_run_leaves_no_folder_and_no_scratch(tmp_path, monkeypatch):
    real = stream_module.spool_chunk

    def failing(options, work):
        if work.number == 1:
            raise RuntimeError("the second chunk's worker died")
        return real(options, work)

    monkeypatch.setattr(stream_module, "spool_chunk", failing)
    with pytest.raises(RuntimeError, match="second chunk"):
        fit_to_folder(_batch(), tmp_path / "out", stream=True, formulas=FORMULAS, jobs=1)
    assert os.listdir(tmp_path) == []


@pytest.mark.slow
def test_the_command_line_streams_a_large_batch_with_the_same_files_and_console(tmp_path, monkeypatch, capsys):
    points = tmp_path / "points.csv"
    pd.concat([p.to_frame() for p in _batch(failures=False)], ignore_index=True).to_csv(points, index=False)
    options = ["--formulas", FORMULAS, "--jobs", "2", "--ci", "0.9"]
    assert main(["fit", str(points), "-o", str(tmp_path / "memory"), *options]) == 0
    kept = capsys.readouterr()
    monkeypatch.setattr(streaming_module, "STREAM_THRESHOLD", 10)
    assert main(["fit", str(points), "-o", str(tmp_path / "streamed"), *options]) == 0
    streamed = capsys.readouterr()
    assert _same_folders(tmp_path / "memory", tmp_path / "streamed") == []
    assert streamed.out.replace("streamed", "memory") == kept.out
    assert streamed.err == kept.err


@pytest.mark.slow
def test_save_of_a_streamed_batch_copies_its_files_and_refuses_what_needs_the_fits(tmp_path):
    streamed, _ = fit_to_folder(_batch(failures=False), tmp_path / "streamed", stream=True, formulas=FORMULAS, jobs=1)
    written = streamed.save(tmp_path / "copy", figures="none")
    warned = ["warnings.csv"] if not streamed.warnings_table().empty else []  # what the batch's data notes say
    assert sorted(written) == ["averages.csv", "fits.csv", "ranking.csv", *warned]
    for name in written:
        assert filecmp.cmp(tmp_path / "streamed" / name, tmp_path / "copy" / name, shallow=False), name
    from tromplab.errors import OptionError

    with pytest.raises(OptionError, match="excel"):
        streamed.save(tmp_path / "other", excel=True)


def test_chunks_typed_differently_are_joined_from_their_rows_into_the_whole_table_s_text(tmp_path):
    """The fallback of the joined files: one chunk's integer column is another's float column
    (``n`` would print ``10`` in one and ``10.0`` in the other), so the texts cannot be glued."""
    import pickle

    from tromplab.output.csv_parts import csv_part, write_csv
    from tromplab.workbench.spool import ChunkSummary, Spool, chunk_file

    chunks = [pd.DataFrame({"experiment": ["a", "b"], "n": [10, 12]}), pd.DataFrame({"experiment": ["c"], "n": [np.nan]})]
    with Spool(tmp_path / "out") as spool:
        for number, frame in enumerate(chunks):
            part = csv_part(frame)
            files = {
                chunk_file("fits", number, "csv"): part.text.encode(),
                chunk_file("fits", number, "pkl"): pickle.dumps(frame),
            }
            layouts = {"fits": (part.columns, part.dtypes, part.rows, False)}
            spool.keep(ChunkSummary(number, {}, 0, 0, [], layouts, None, None, None, files))
        spool.table_writer("fits")(tmp_path / "joined.csv")
        glued = tmp_path / "glued.csv"
        write_csv(pd.concat(chunks, ignore_index=True), glued)
        assert (tmp_path / "joined.csv").read_text() == glued.read_text()
        assert "10.0" in glued.read_text()  # the whole table's type, not the first chunk's
    assert not any(p.name.startswith(".out.tmp") for p in tmp_path.iterdir())  # the scratch folder is gone


@pytest.mark.slow
def test_per_experiment_figures_keep_the_fits_in_memory(tmp_path):
    """``figures="auto"`` draws every fitted experiment up to 20 of them (failed ones not
    counted): those figures need the fits, so the batch is not streamed whatever ``stream`` says."""
    data = _batch(19)  # 19 fitted and two failed: 21 experiments, per-experiment figures
    bench, written = fit_to_folder(data, tmp_path / "out", stream=True, formulas="plitt", jobs=1)
    assert isinstance(bench.store, FitsInMemory) and "figures.csv" in written and "overview.png" not in written


@pytest.mark.slow
def test_a_killed_streamed_run_leaves_only_a_scratch_folder_that_the_next_run_removes(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    from tromplab.output.outputs import clean_stale

    points = tmp_path / "points.csv"
    pd.concat([p.to_frame() for p in _batch(failures=False)], ignore_index=True).to_csv(points, index=False)
    script = (
        "import sys; from tromplab.loading.lab import read_experiments; from tromplab.workbench import fit_to_folder; "
        "fit_to_folder(read_experiments(sys.argv[1]), sys.argv[2], stream=True, jobs=1)"
    )
    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, "-c", script, str(points), str(out)])
    deadline = time.monotonic() + 120
    while not any(p.name.startswith(".out.tmp-") for p in tmp_path.iterdir()) and time.monotonic() < deadline:
        time.sleep(0.05)
    process.send_signal(signal.SIGKILL)  # no handler runs: the scratch folder stays behind
    process.wait(timeout=30)
    left = [p.name for p in tmp_path.iterdir() if p.name != "points.csv"]
    assert not out.exists() and len(left) == 1 and left[0].startswith(f".out.tmp-{process.pid}-")
    assert [p.name for p in clean_stale(out)] == left  # named as a staging folder of a dead run
    assert sorted(p.name for p in tmp_path.iterdir()) == ["points.csv"]


@pytest.mark.slow
def test_a_streamed_workbench_pickles_without_its_fits_and_still_refits(tmp_path):
    import pickle

    streamed, _ = fit_to_folder(_batch(failures=False), tmp_path / "out", stream=True, formulas=FORMULAS, jobs=1)
    made = streamed.fit("s5", "plitt")
    copy = pickle.loads(pickle.dumps(streamed))
    assert "_refits" not in copy.__dict__ and copy.experiments == streamed.experiments
    assert copy.fit("s5", "plitt").fit.ssr == made.fit.ssr
    pd.testing.assert_frame_equal(copy.ranking_table(), streamed.ranking_table())


def _points_file(path, data, *, interleaved=False):
    """``data`` written as a points file; ``interleaved``: the experiments' rows mixed (row i of each, then i + 1)."""
    frame = pd.concat([p.to_frame() for p in data], ignore_index=True)
    if interleaved:
        frame = frame.iloc[np.argsort(frame.groupby("experiment", sort=False).cumcount().to_numpy(), kind="stable")]
    frame.to_csv(path, index=False)
    return path


def _lab_file(path, *, copies=30, interleaved=False):
    """The bundled lab table's experiments ``copies`` times over (renamed), as one lab table."""
    frame = read_table(DATASETS / "double_deck_screen_decks_lab.csv").frame
    frame = pd.concat([frame.assign(experiment=frame["experiment"] + f" {copy}") for copy in range(copies)], ignore_index=True)
    if interleaved:  # the classes of each experiment stay in order, as a lab table needs
        frame = frame.iloc[np.argsort(frame.groupby("experiment", sort=False).cumcount().to_numpy(), kind="stable")]
    frame.to_csv(path, index=False)
    return path


@pytest.mark.parametrize("jobs", [1, 2])
@pytest.mark.parametrize("interleaved", [False, True])
@pytest.mark.slow
def test_a_points_file_read_in_pieces_streams_the_folder_of_the_whole_file(tmp_path, jobs, interleaved):
    path = _points_file(tmp_path / "points.csv", _batch(), interleaved=interleaved)
    options = {"formulas": FORMULAS, "jobs": jobs, "ci": 0.9}
    kept, _ = fit_to_folder(str(path), tmp_path / "memory", stream=False, **options)
    source = ExperimentsInPieces(path, piece_rows=37)  # pieces that cut experiments, two chunks of 64 and more
    streamed, written = fit_to_folder(source, tmp_path / "streamed", stream=True, **options)
    assert isinstance(streamed.store, FitsOnDisk) and "failures.csv" in written
    assert _same_folders(tmp_path / "memory", tmp_path / "streamed") == []
    assert streamed.inputs is source  # not held in memory: a refit reads the file again
    assert streamed.fit("s5", "plitt").fit.ssr == kept.fit("s5", "plitt").fit.ssr


@pytest.mark.parametrize("jobs", [1, 2])
@pytest.mark.parametrize("interleaved", [False, True])
@pytest.mark.slow
def test_a_lab_table_read_in_pieces_streams_the_folder_of_the_whole_table(tmp_path, jobs, interleaved):
    path = _lab_file(tmp_path / "lab.csv", interleaved=interleaved)
    options = {"formulas": FORMULAS, "jobs": jobs, "figures": "none"}
    lab = LabOptions(size_unit="mm", min_feed_share=0.05)  # some classes left out: left_out.csv and notes
    kept, _ = fit_to_folder(read_experiments(path, lab), tmp_path / "memory", stream=False, **options)
    source = ExperimentsInPieces(path, lab, piece_rows=11)
    streamed, written = fit_to_folder(source, tmp_path / "streamed", stream=True, **options)
    assert isinstance(streamed.store, FitsOnDisk) and "left_out.csv" in written
    assert _same_folders(tmp_path / "memory", tmp_path / "streamed") == []
    whole = {b.experiment: b for b in kept.balances}
    assert [(b.experiment, b.notes, b.left_out_summary()) for b in source.balances] == [
        (b.experiment, b.notes, b.left_out_summary()) for b in kept.balances if b.notes or b.left_out_summary()
    ]
    assert whole and len(source.balances) > 0


@pytest.mark.slow
def test_a_source_read_in_pieces_is_read_whole_when_the_run_keeps_its_fits(tmp_path):
    path = _lab_file(tmp_path / "lab.csv", copies=2)
    lab = LabOptions(size_unit="mm", min_feed_share=0.05)
    kept, _ = fit_to_folder(read_experiments(path, lab), tmp_path / "memory", formulas=FORMULAS, figures="best")
    again, _ = fit_to_folder(ExperimentsInPieces(path, lab), tmp_path / "pieces", formulas=FORMULAS, figures="best")
    assert isinstance(again.store, FitsInMemory)
    assert [b.experiment for b in again.balances] == [b.experiment for b in kept.balances]
    assert _same_folders(tmp_path / "memory", tmp_path / "pieces") == []


@pytest.mark.parametrize("kind", ["points", "lab"])
@pytest.mark.slow
def test_the_command_line_reads_a_large_csv_in_pieces_with_the_same_files_and_console(tmp_path, monkeypatch, capsys, kind):
    if kind == "points":
        path, options = _points_file(tmp_path / "points.csv", _batch(), interleaved=True), []
    else:
        path, options = _lab_file(tmp_path / "lab.csv", interleaved=True), ["--size-unit", "mm", "--min-feed-share", "0.05"]
    options += ["--formulas", FORMULAS, "--jobs", "2", "--no-figures"]
    assert main(["fit", str(path), "-o", str(tmp_path / "memory"), *options]) in (0, 3)
    kept = capsys.readouterr()
    monkeypatch.setattr(streaming_module, "IN_PIECES_FROM_BYTES", 0)
    monkeypatch.setattr(streaming_module, "STREAM_THRESHOLD", 10)
    read = []
    monkeypatch.setattr(ExperimentsInPieces, "census", _recording(ExperimentsInPieces.census, read))
    assert main(["fit", str(path), "-o", str(tmp_path / "streamed"), *options]) in (0, 3)
    streamed = capsys.readouterr()
    assert read, "the input was read whole"
    assert _same_folders(tmp_path / "memory", tmp_path / "streamed") == []
    assert streamed.out.replace("streamed", "memory") == kept.out
    assert streamed.err == kept.err
    assert kind == "points" or "left_out.csv" in streamed.err  # the balance notes, grouped with the other warnings


def _recording(method, calls):
    def recorded(self):
        calls.append(self.path)
        return method(self)

    return recorded


@pytest.mark.parametrize("kind", ["points", "lab"])
@pytest.mark.slow
def test_a_bad_row_deep_in_a_file_read_in_pieces_is_exit_1_with_nothing_written_before_any_fit(
    tmp_path, monkeypatch, capsys, kind
):
    if kind == "points":
        path = _points_file(tmp_path / "points.csv", _batch(failures=False))
        options = []
    else:
        path = _lab_file(tmp_path / "lab.csv")
        options = ["--size-unit", "mm"]
    lines = path.read_text().splitlines()
    cells = lines[-5].split(",")
    cells[-1 if kind == "points" else 3] = "abc"  # a partition / a feed share that is no number
    lines[-5] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    args = ["fit", str(path), "--formulas", FORMULAS, "--jobs", "2", "--no-figures", *options]
    assert main([*args, "-o", str(tmp_path / "whole")]) == 1
    whole = capsys.readouterr()
    monkeypatch.setattr(streaming_module, "IN_PIECES_FROM_BYTES", 0)
    monkeypatch.setattr(streaming_module, "STREAM_THRESHOLD", 10)
    fitted = []
    monkeypatch.setattr(stream_module, "_streamed_batch", lambda *a: fitted.append(a))
    assert main([*args, "-o", str(tmp_path / "pieces")]) == 1
    pieces = capsys.readouterr()
    assert fitted == [] and sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    assert pieces.err == whole.err
    assert "abc" in pieces.err and str(len(lines) - 4) in pieces.err  # the cell and its line, as the whole reader names them


def _main_process_memory(tmp_path, monkeypatch, experiments, *, in_pieces) -> tuple[int, int]:
    """The peak of the main process's Python allocations (tracemalloc) until the folder is
    written, and the most experiments' points alive in it as the chunks come back, while it
    fits a points file of ``experiments`` (streamed, two workers), read whole or in pieces."""
    import gc
    import tracemalloc

    from tromplab.workbench.spool import Spool

    rng = np.random.default_rng(experiments)
    size = 5.0 * 2.0 ** np.arange(12) / 8
    cut = rng.uniform(2, 20, (experiments, 1))
    partition = np.clip(1 / (1 + (size / cut) ** 3) + rng.normal(0, 0.01, (experiments, size.size)), 0, 1).round(4)
    path = tmp_path / f"points_{experiments}.csv"
    names = np.repeat([f"survey {i:06d}" for i in range(experiments)], size.size)
    pd.DataFrame({"experiment": names, "size": np.tile(size, experiments), "partition_fine": partition.ravel()}).to_csv(
        path, index=False
    )
    alive, fitted = [], []
    keep, write = Spool.keep, stream_module.write_streamed_folder

    def counted(spool, summary):
        # this file's points only: a test run before this one may have left points of its own
        alive.append(sum(isinstance(found, TrompPoints) and path.name in str(found.source) for found in gc.get_objects()))
        return keep(spool, summary)

    monkeypatch.setattr(Spool, "keep", counted)
    monkeypatch.setattr(
        stream_module,
        "write_streamed_folder",
        lambda *a, **k: (fitted.append(tracemalloc.get_traced_memory()[1]), write(*a, **k))[1],
    )
    tracemalloc.start()
    try:
        source = ExperimentsInPieces(path, piece_rows=2000) if in_pieces else read_experiments(path)
        fit_to_folder(source, tmp_path / f"out_{experiments}_{in_pieces}", stream=True, formulas="plitt", figures="none", jobs=2)
        del source
        return fitted[0], max(alive)
    finally:
        tracemalloc.stop()


@pytest.mark.slow
def test_the_main_process_holds_no_points_of_the_batch_when_the_file_is_read_in_pieces(tmp_path, monkeypatch):
    """Five times the experiments (chunks of 64, so that the chunks in flight are as large for
    both sizes): read whole, the main process holds every experiment's points while the chunks
    are fitted; read in pieces, those of the chunks in flight only, as many for both sizes.
    (The peaks of its allocations, printed, are measured at larger sizes by
    benchmarks/fit_in_pieces_memory.py: here the per-experiment names and ranks and the
    transients of the reading weigh as much as the points.)"""
    monkeypatch.setattr(fanout_module, "MAX_CHUNK_SIZE", 64)
    small, large = 200, 1000
    pieces = {n: _main_process_memory(tmp_path, monkeypatch, n, in_pieces=True) for n in (small, large)}
    whole = {n: _main_process_memory(tmp_path, monkeypatch, n, in_pieces=False) for n in (small, large)}
    print({"in pieces": pieces, "whole": whole})
    assert whole[small][1] >= small and whole[large][1] >= large
    in_flight = fanout_module.CHUNKS_IN_FLIGHT * 2 * 64
    assert pieces[small][1] <= in_flight + 64 and pieces[large][1] <= in_flight + 64  # a chunk being cut too


@pytest.mark.parametrize(
    ("suffix", "options", "expected"),
    [
        (".csv", [], True),
        (".csv", ["--no-figures"], True),
        (".csv", ["--excel"], False),
        (".csv", ["--figures", "best"], False),
        (".csv", ["--format", "parquet"], False),
        (".xlsx", [], False),
    ],
)
def test_the_command_line_reads_in_pieces_only_a_large_csv_whose_results_can_stream(
    tmp_path, monkeypatch, suffix, options, expected
):
    from tromplab.cli import build_parser

    path = tmp_path / f"input{suffix}"
    path.write_bytes(b"x" * 64)
    args = build_parser().parse_args(["fit", str(path), "-o", str(tmp_path / "out"), *options])
    monkeypatch.setattr(streaming_module, "IN_PIECES_FROM_BYTES", 64)
    assert fit_command.reads_in_pieces(args) is expected
    monkeypatch.setattr(streaming_module, "IN_PIECES_FROM_BYTES", 65)  # below the size: read whole
    assert fit_command.reads_in_pieces(args) is False


def _ranking_joined_and_whole(tmp_path, chunks, equations, caplog) -> tuple[str, str, bool]:
    """``ranking.csv`` joined from the rank files of ``chunks`` (tidy tables of per-experiment
    scores, one per chunk) by :meth:`Spool.ranking_writer`, the same table ranked whole and
    written by ``write_csv`` as ``Workbench.ranking_table`` orders it, and whether the join
    fell back to the table in memory."""
    import logging

    from tromplab.curves.ranking import rank_formulas
    from tromplab.output.csv_parts import write_csv
    from tromplab.workbench.spool import ChunkSummary, Spool, chunk_file, chunk_ranks

    whole = rank_formulas(pd.concat(chunks, ignore_index=True), key="formula")
    table = whole.copy()
    table.insert(0, "equation", table["formula"].map(equations))
    table = table.sort_values(["place", "equation"]).reset_index(drop=True)
    write_csv(table, tmp_path / "whole.csv")
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="tromplab.workbench"), Spool(tmp_path / "out") as spool:
        start = 0
        for number, tidy in enumerate(chunks):
            names = list(dict.fromkeys(tidy["experiment"]))
            ranks, content = chunk_ranks(rank_formulas(tidy, key="formula"), names, start)
            (spool.scratch / chunk_file("ranking", number, "csv")).write_bytes(content)
            spool.keep(ChunkSummary(number, {}, 0, 0, [], {}, ranks, None, None, {}))
            start += len(names)
        batch = spool.ranks([name for tidy in chunks for name in dict.fromkeys(tidy["experiment"])])
        pd.testing.assert_frame_equal(batch.frame(), whole)  # the table Workbench.ranking_table starts from
        spool.ranking_writer(batch, equations, lambda: table)(tmp_path / "joined.csv")
    in_memory = any("formatted in memory" in record.getMessage() for record in caplog.records)
    return (tmp_path / "joined.csv").read_bytes(), (tmp_path / "whole.csv").read_bytes(), in_memory


def _scores(names, formulas=("a", "b", "c"), seed=0):
    """A tidy table of F scores of ``formulas`` for each experiment of ``names`` (ties included)."""
    rng = np.random.default_rng(seed)
    rows = [
        {"experiment": name, "formula": formula, "adequate": bool(rng.integers(2)), "F": float(rng.integers(1, 4))}
        for name in names
        for formula in formulas
    ]
    return pd.DataFrame(rows)


ODD_NAMES = {
    "plain": ["s1", "s2", "s3"],
    "quotes and commas": ['a "quoted", name', "b,c", "d'e"],
    "formula-like": ["=1+1", "-3", "+x", "@sum"],
    "unicode and spaces": ["Zürich  2", " lead", "trail "],
    "a line break": ["first\nsecond", "third"],
    "numbers": ["1", "2.50", "1e3"],
}


@pytest.mark.parametrize("names", list(ODD_NAMES))
def test_ranking_csv_joined_from_the_chunks_is_the_whole_table_s_text(tmp_path, caplog, names):
    """One, two and many chunks (a chunk of one experiment among them), odd experiment names
    and a formula that one chunk ranked no fit of (its cells there are empty)."""
    chosen = ODD_NAMES[names]
    equations = {"a": "(1)", "b": "(2), shifted", "c": '"Plitt"'}
    many = [_scores([f"{name} {i}" for name in chosen], seed=i) for i in range(4)]
    many[2] = many[2][many[2]["formula"] != "b"]  # no fit of b ranked in that chunk
    many.append(_scores([f"{chosen[0]} last"], seed=9).assign(F=[2.0, np.nan, 1.0]).dropna())  # one experiment, b unranked
    for chunks in ([many[0]], many[:2], many):
        joined, whole, in_memory = _ranking_joined_and_whole(tmp_path, chunks, equations, caplog)
        assert joined == whole
        assert not in_memory  # joined from the files, not formatted whole
    line_b = joined[joined.index(b",b,") :].split(os.linesep.encode())[0]
    assert b",," in line_b  # the empty cells of the chunks that ranked no fit of b


def test_ranking_csv_with_a_carriage_return_in_a_name_is_formatted_in_memory_with_the_same_text(tmp_path, caplog):
    """A carriage return in a cell makes ``write_csv`` quote every text, which the chunks' texts
    cannot know: the table is formatted whole (the fallback), with the same bytes."""
    chunks = [_scores(["s1", "carriage\rreturn"]), _scores(["s3", "s4"], seed=1)]
    joined, whole, in_memory = _ranking_joined_and_whole(tmp_path, chunks, {"a": "(1)", "b": "(2)", "c": "(3)"}, caplog)
    assert joined == whole and in_memory
    assert b'"s1"' in whole  # every text quoted


@pytest.mark.parametrize("gather", [False, True])
@pytest.mark.slow
def test_a_streamed_batch_of_odd_names_in_many_chunks_writes_the_in_memory_folder(tmp_path, monkeypatch, caplog, gather):
    """Chunks of 8 experiments on two workers (and the gather mode of a Dask cluster whose
    workers cannot see the folder), experiments named with commas, quotes, formula marks and a
    line break, two the screen cannot judge: the folder is the in-memory path's, ranking.csv
    joined from the chunks' files."""
    import logging

    monkeypatch.setattr(fanout_module, "MAX_CHUNK_SIZE", 8)
    monkeypatch.setattr(fanout_module, "CHUNK_SIZE", 8)
    odd = ['a "quoted", name', "=1+1", "-3", "Zürich", "line\nbreak", "b,c"]
    data = [p if i >= len(odd) else TrompPoints(odd[i], p.size, p.partition_fine) for i, p in enumerate(_batch(40))]
    options = {"formulas": FORMULAS, "jobs": 2}
    kept, _ = fit_to_folder(data, tmp_path / "memory", stream=False, **options)
    if gather:
        monkeypatch.setattr(stream_module, "_workers_see", lambda cluster, folder: False)
    with caplog.at_level(logging.INFO, logger="tromplab.workbench"):
        streamed, written = fit_to_folder(data, tmp_path / "streamed", stream=True, **options)
    assert len(streamed.store.ranks.pieces) == 5  # 40 fitted experiments in chunks of 8
    assert not any("in memory" in record.getMessage() for record in caplog.records)
    assert "overview.png" in written
    assert _same_folders(tmp_path / "memory", tmp_path / "streamed") == []
    pd.testing.assert_frame_equal(streamed.ranking_table(), kept.ranking_table())


@pytest.mark.slow
def test_a_streamed_run_writes_its_folder_without_making_the_ranking_table(tmp_path, monkeypatch):
    """The table with a column per experiment is what grew with the batch in the main process:
    a streamed run writes ``ranking.csv`` without it (made only when ``ranking_table`` is asked
    for), and draws the overview from the values kept per chunk."""
    from tromplab.workbench.spool import BatchRanks

    data = _batch()
    fit_to_folder(data, tmp_path / "memory", stream=False, formulas=FORMULAS, jobs=1)
    made = BatchRanks.frame

    def refused(self):
        raise AssertionError("the ranking table was made")

    monkeypatch.setattr(BatchRanks, "frame", refused)
    streamed, written = fit_to_folder(data, tmp_path / "streamed", stream=True, formulas=FORMULAS, jobs=1)
    assert "overview.png" in written
    assert _same_folders(tmp_path / "memory", tmp_path / "streamed") == []
    monkeypatch.setattr(BatchRanks, "frame", made)
    monkeypatch.setattr(BatchRanks, "frame", refused)
    standings = streamed.ranking_table(per_experiment=False)  # what the console shows of a large batch
    monkeypatch.setattr(BatchRanks, "frame", made)
    ranking = streamed.ranking_table()
    assert ranking.shape == (3, 2 + 70 + 2)  # equation, formula, the 70 fitted experiments, points, place
    columns = ["equation", "formula", "points", "place"]
    pd.testing.assert_frame_equal(standings, ranking[columns])
    assert streamed.ranking_table(per_experiment=False).equals(standings)


@pytest.mark.slow
def test_the_console_ranks_a_large_batch_by_points_and_leaves_each_experiment_s_ranks_to_the_file(tmp_path, capsys):
    """Beyond the console's experiments, a column per experiment would neither be read nor fit a
    line: the console shows each formula's points and place and names the file with the ranks."""
    data = _batch(failures=False)
    _points_file(tmp_path / "points.csv", data)
    assert main(["fit", str(tmp_path / "points.csv"), "-o", str(tmp_path / "out"), "--formulas", FORMULAS,
                 "--jobs", "1", "--figures", "none"]) == 0  # fmt: skip
    console = capsys.readouterr().out
    note = "(the rank of each formula in each experiment is in ranking.csv)"
    ranking = console[console.index("Ranking across experiments") : console.index(note) + len(note)].splitlines()
    assert ranking[1].split() == ["equation", "formula", "points", "place"]
    assert len(ranking) == 2 + len(FORMULAS.split(",")) + 1
    written = pd.read_csv(tmp_path / "out" / "ranking.csv")
    assert written.shape[1] == 2 + len(data) + 2
    for line in ranking[2:-1]:
        equation, formula, points, place = line.split()
        row = written[written["formula"] == formula].iloc[0]
        assert float(points) == pytest.approx(row["points"]) and int(place) == row["place"]
