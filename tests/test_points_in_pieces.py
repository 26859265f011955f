"""A points file read in pieces (``iter_experiments``) gives what the whole-file reader
(``read_points``) gives: the same points in the same order, or the same error (file, row,
column, words), for the hostile and messy inputs of the loaders' tests, any piece size and
experiments in any order; and its memory is bounded by the piece, not the file."""

import tracemalloc
import warnings

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tromplab.errors import InputError, InputNote
from tromplab.loading.lab import LabOptions, balances_from_table, read_lab
from tromplab.loading.points import iter_experiments, read_points
from tromplab.loading.tables import iter_experiment_tables, read_table, read_table_in_pieces

from .conftest import DATASETS
from .hostile_names import NAMES, distinct_as_read, points_rows
from .strategies import mutated, points_tables, write_frame
from .test_hostile_inputs import FILE_CASES, POINTS, TEXT_CASES

PIECES = (1, 2, 3, 1000)


def outcome(read):
    """What a reader makes of a file: its experiments (name, unit, source and arrays) and the
    notes it warned of, or the error's message."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            points = list(read())
        except InputError as error:
            return ("error", str(error))
    notes = sorted({str(w.message) for w in caught if issubclass(w.category, InputNote)})
    return (
        "points",
        notes,
        [
            (p.experiment, p.size_unit, p.source, p.size.tolist(), p.partition_fine.tolist(),
             None if p.weight is None else p.weight.tolist())
            for p in points
        ],
    )  # fmt: skip


def assert_same_in_pieces(path, **options):
    whole = outcome(lambda: read_points(path, **options))
    for piece_rows in PIECES:
        assert outcome(lambda rows=piece_rows: iter_experiments(path, piece_rows=rows, **options)) == whole, piece_rows
    return whole


def _options(argv) -> dict:
    """The reader's keywords of a test case's command-line options (None for a lab-table option)."""
    names = {"--sep": "sep", "--decimal": "decimal", "--size-unit": "size_unit"}
    if any(flag.startswith("--") and flag not in names for flag in argv[::2]):
        return None
    return {names[flag]: value for flag, value in zip(argv[::2], argv[1::2])}


@pytest.mark.parametrize("text, options, expected", TEXT_CASES, ids=[e[:70] for _, _, e in TEXT_CASES])
def test_the_hostile_text_tables_give_the_same_outcome_in_pieces(tmp_path, text, options, expected):
    keywords = _options(options)
    if keywords is None:
        pytest.skip("a lab-table option")
    path = tmp_path / "input.csv"
    path.write_text(text)
    try:
        assert_same_in_pieces(path, **keywords)
    except TypeError:  # an option refused before any reading (a separator of two characters)
        with pytest.raises(InputError):
            read_points(path, **keywords)


@pytest.mark.parametrize("name, make, expected", FILE_CASES, ids=[c[0] for c in FILE_CASES])
def test_files_that_are_not_csv_text_are_refused_in_pieces_as_whole(tmp_path, name, make, expected):
    path = tmp_path / name
    make(path)
    assert assert_same_in_pieces(path)[0] == "error"  # the words checked by the command line's test


@pytest.mark.slow
def test_names_stay_text_in_pieces(tmp_path):
    path = tmp_path / "names.csv"
    pd.DataFrame(points_rows(distinct_as_read(NAMES))).to_csv(path, index=False)
    whole = assert_same_in_pieces(path)
    names = [experiment[0] for experiment in whole[2]]
    assert {"01", "1", "NA"} <= set(names)


@pytest.mark.parametrize(
    "text",
    [
        "# a comment\n\nexperiment,size,partition_fine\nA,10,0.9\nA,20,0.5\nA,40,0.1\n",
        "  # indented comment\nexperiment,size,partition_fine\nA,10,0.9\n\n#B,20,0.5\nA,20,0.4\n#B,40,0.2\nA,40,0.1\n#B,80,0.1\n",
        "experiment,size,partition_fine\r\n#A,10,0.9\r\n\r\n#A,20,0.5\r\n#A,40,0.2\r\n",
        "experiment,size,partition_fine\r#A,10,0.9\r#A,20,0.5\r#A,40,0.2\r",
        "experiment;size;partition_fine\n01;10;0,9\n1;10;0,8\n01;20;0,5\n1;20;0,4\n01;40;0,1\n1;40;0,2\n",
        "experiment,size_um,partition_fine_pct,weight,used\nNA,10,90,1,yes\nNA,20,50,2,no\nNA,20,55,1,yes\nNA,40,10,1,1\n",
        '"experiment",size,partition_fine\n"a, b",10,0.9\n"a, b",20,0.5\n"a\nb",40,0.1\n"a, b",40,0.2\n',
        "experiment,size,partition_fine\nA,10,0.9\nA,20,0.5\nB,10,0.9\nA,10,0.1\n",
        "experiment,size,partition_fine,used\nA,10,0.9,no\nA,20,0.5,no\nA,40,0.1,no\n",
        "experiment,size,partition_fine,used\nA,10,0.9,no\nA,20,0.5,maybe\nA,40,0.1,no\n",
        "experiment,size,partition_fine\nA,10,0.9\nA,20,0.5\nA,40,0.1\n,,\n",
        "experiment,size,partition_fine\n",
    ],
    ids=["comments", "hash names", "crlf", "old mac", "decimal commas", "units used weights", "quoted",
         "repeated size", "nothing used", "bad mark", "blank row", "header only"],
)  # fmt: skip
def test_messy_layouts_give_the_same_outcome_in_pieces(tmp_path, text):
    path = tmp_path / "messy.csv"
    path.write_bytes(text.encode())
    assert_same_in_pieces(path)


def test_the_per_cent_hint_is_decided_on_the_rows_up_to_the_fault_in_pieces_as_whole(tmp_path):
    """Shares in per cent (the first out of range 50) with a larger value further down (400, in a
    later piece): both readers see the rows up to the fault alike and give the hint (a property
    test found the whole reader, which had looked at the whole column, without it)."""
    path = tmp_path / "per cent.csv"
    path.write_text("experiment,size,partition_fine\nA,10,0.5\nA,20,50\nA,40,400\n")
    kind, message = assert_same_in_pieces(path)
    assert kind == "error" and message.endswith(
        "row 3, column 'partition_fine': partition 50 outside 0..1: these look like percentages; name the column "
        "partition_fine_pct (0..100) or divide by 100"
    )


def test_the_first_fault_named_is_the_whole_readers_first_though_a_later_piece_holds_it(tmp_path):
    """The whole-file reader checks column by column (sizes before partitions): a bad size in
    row 40 is named before a bad partition in row 3, also when they are in different pieces."""
    rows = [f"A{i // 5},{10 * (1 + i % 5)},0.5" for i in range(50)]
    rows[1] = "A0,20,1.7"  # row 3: partition outside 0..1
    rows[38] = "A7,abc,0.5"  # row 40: not a number
    path = tmp_path / "two faults.csv"
    path.write_text("experiment,size,partition_fine\n" + "\n".join(rows) + "\n")
    whole = assert_same_in_pieces(path)
    assert whole == ("error", f"{path}, row 40, column 'size': 'abc' is not a number")


@pytest.mark.slow
def test_a_byte_that_is_not_utf8_deep_in_the_file_is_named_by_its_line(tmp_path):
    path = tmp_path / "latin.csv"
    lines = ["experiment,size,partition_fine"] + [f"A{i // 5},{10 * (1 + i % 5)},0.5" for i in range(3000)]
    path.write_bytes("\n".join(lines).encode() + "\nProbe é,10,0.9\n".encode("latin-1"))
    assert assert_same_in_pieces(path)[1].endswith("row 3002: the text is not UTF-8 (byte 0xe9 cannot be decoded): save the file as UTF-8 (in Excel: CSV UTF-8)")  # fmt: skip


@pytest.mark.slow
def test_experiments_in_any_order_come_in_order_of_first_appearance(tmp_path):
    rng = np.random.default_rng(3)
    frame = pd.DataFrame(points_rows([f"run {i}" for i in range(40)]))
    path = write_frame(frame.iloc[rng.permutation(len(frame))], tmp_path / "shuffled.csv")
    whole = assert_same_in_pieces(path)
    assert len(whole[2]) == 40


def test_a_workbook_and_a_frame_are_read_whole(tmp_path):
    frame = pd.DataFrame(points_rows(["01", "1"]))
    frame.to_excel(tmp_path / "points.xlsx", index=False)
    assert [p.experiment for p in iter_experiments(tmp_path / "points.xlsx")] == ["01", "1"]
    assert [p.experiment for p in iter_experiments(frame)] == ["01", "1"]
    assert len(list(read_table_in_pieces(frame, piece_rows=1))) == 1


def test_the_pieces_hold_the_rows_of_the_whole_table(tmp_path):
    path = tmp_path / "points.csv"
    path.write_text("# lab 3\n" + POINTS.replace("\n40,", "\n\n40,"))
    pieces = list(read_table_in_pieces(path, piece_rows=2))
    assert [len(piece.frame) for piece in pieces] == [2, 2, 1]
    assert np.concatenate([piece.rows for piece in pieces]).tolist() == read_table(path).rows.tolist() == [3, 4, 6, 7, 8]
    with pytest.raises(ValueError, match="piece_rows must be at least 1"):
        next(read_table_in_pieces(path, piece_rows=0))


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=points_tables(), mutation=mutated(), piece_rows=st.integers(1, 7), seed=st.integers(0, 2**32 - 1))
@pytest.mark.slow
def test_mutated_points_tables_give_the_same_outcome_in_pieces(tmp_path_factory, case, mutation, piece_rows, seed):
    frame = mutation(case.frame, case)
    frame = frame.iloc[np.random.default_rng(seed).permutation(len(frame))]  # experiments interleaved
    path = write_frame(frame, tmp_path_factory.mktemp("pts") / "points.csv")
    assert outcome(lambda: iter_experiments(path, piece_rows=piece_rows)) == outcome(lambda: read_points(path))


def _peak_bytes(read) -> int:
    tracemalloc.start()
    try:
        read()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.slow
def test_the_memory_of_reading_in_pieces_is_bounded_by_the_piece(tmp_path):
    """40,000 rows (4,000 experiments) in pieces of 500 rows: the peak of the reading stays
    under a third of the whole-file reader's, which holds every row and experiment; what
    remains is a piece and the first pass's count of each experiment's rows
    (benchmarks/points_in_pieces.py measures 200,000 rows)."""
    experiments = 4000
    sizes = np.tile(10.0 * 2.0 ** np.arange(10), experiments)
    frame = pd.DataFrame({"experiment": np.repeat([f"survey {i}" for i in range(experiments)], 10), "size": sizes,
                          "partition_fine": np.tile(np.linspace(0.99, 0.01, 10), experiments)})  # fmt: skip
    path = write_frame(frame, tmp_path / "large.csv")
    count = {"n": 0}

    def consume():
        for _ in iter_experiments(path, piece_rows=500):
            count["n"] += 1

    whole = _peak_bytes(lambda: read_points(path))
    pieces = _peak_bytes(consume)
    assert count["n"] == experiments
    assert pieces < whole / 3, (pieces, whole)


@pytest.mark.parametrize("shuffled", [False, True])
@pytest.mark.slow
def test_a_lab_table_balances_the_same_experiment_by_experiment_in_pieces(tmp_path, shuffled):
    """What a lab reader in pieces would do: the mass balance of each experiment's table from
    ``iter_experiment_tables`` gives the points of the whole-table reader, rows in any order."""
    frame = read_table(DATASETS / "double_deck_screen_decks_lab.csv").frame
    frame = pd.concat([frame.assign(experiment=frame["experiment"] + f" {copy}") for copy in range(4)], ignore_index=True)
    if shuffled:
        # experiments interleaved row by row (the classes of each stay in order, as a lab table needs)
        frame = frame.iloc[np.argsort(frame.groupby("experiment", sort=False).cumcount().to_numpy(), kind="stable")]
    path = write_frame(frame, tmp_path / "lab.csv")
    options = LabOptions(size_unit="mm")
    whole = [balance.to_points() for balance in read_lab(path, options)]
    tables = list(iter_experiment_tables(path, piece_rows=3))
    pieces = [balance.to_points() for table in tables for balance in balances_from_table(table, options)]
    assert [p.experiment for p in pieces] == [p.experiment for p in whole]
    for a, b in zip(pieces, whole):
        assert a.size.tolist() == b.size.tolist() and a.partition_fine.tolist() == b.partition_fine.tolist()
    assert sorted(np.concatenate([t.rows for t in tables]).tolist()) == list(range(2, len(frame) + 2))
