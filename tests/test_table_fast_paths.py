"""The CSV reader's fast paths (a 90,000-row fits.csv) give the answers of their plain
definitions for every input: the test for comment and blank lines, the count of fields per record
(quotes spanning blocks, records spanning blocks, a last record without a line break), and the
yes/no marks of a column already parsed as booleans."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tromplab.errors import InputError
from tromplab.loading.tables import (
    _first_lines,
    _lines_to_skip,
    _long_records_in,
    is_comment_or_blank,
    read_table,
    table_from_frame,
)

LINE_TEXT = st.text(alphabet=" \t\r\n#a,\v", max_size=30)


def _skips_a_line(text: str) -> bool:
    """The plain definition: the first line is a comment or blank, or a later line is blank
    (spaces and tabs only; a line ends at a line feed, the carriage return before it dropped)."""
    lines = [line[:-1] if line.endswith("\r") else line for line in text.split("\n")]
    assert is_comment_or_blank(lines[0]) == (lines[0].lstrip(" \t").startswith("#") or not lines[0].strip(" \t"))
    return is_comment_or_blank(lines[0]) or any(not line.strip(" \t") for line in lines[1:])


@settings(max_examples=3000, deadline=None)
@given(text=LINE_TEXT, data=st.data())
@pytest.mark.slow
def test_lines_to_skip_are_found_as_the_plain_definition_finds_them(text, data):
    end = data.draw(st.integers(0, len(text)))
    assert _lines_to_skip(text, end) == _skips_a_line(text[:end])


@pytest.mark.parametrize(
    "text, found",
    [
        ("a,b\n1,2\n", False),
        ("# note\na,b\n1,2", True),  # the first line
        ("  \t# note\na,b", True),
        ("a,b\n#3,2", False),  # below the header a '#' line is data
        ("a,b\n\n1,2", True),  # a blank line
        ("a,b\r\n\r\n1,2", True),  # a blank line of a CRLF file
        ("a,b\r\n \t\r\n1,2", True),  # whitespace only
        ("a,b\n \v\n1,2", False),  # a vertical tab is content
        ("a,b\r\n1,#2\r\n", False),  # a '#' inside a line is text
        ("a,b\n1,2\n   ", True),  # trailing spaces make a last blank line
    ],
)
def test_lines_to_skip_cases(text, found):
    end = len(text.rstrip("\r\n"))
    assert _lines_to_skip(text, end) == found == _skips_a_line(text[:end])


def _has_long_record(text: str, sep: str, expected: int) -> bool:
    """The plain definition: fields per record after the header, separators and line breaks
    inside double quotes not counted."""
    inside, fields, records = False, 1, []
    for character in text:
        if character == '"':
            inside = not inside
        elif character == sep and not inside:
            fields += 1
        elif character == "\n" and not inside:
            records.append(fields)
            fields = 1
    if text and (not text.endswith("\n") or inside):
        records.append(fields)  # the last record, without its line break
    return any(count > expected for count in records[1:])


@settings(max_examples=3000, deadline=None)
@given(
    text=st.text(alphabet='",;\na', max_size=60),
    block=st.integers(1, 17),
    expected=st.integers(1, 5),
    sep=st.sampled_from([",", ";"]),
)
@pytest.mark.slow
def test_long_records_are_found_across_blocks_as_the_plain_count_finds_them(text, block, expected, sep):
    data = text.encode()
    blocks = [data[i : i + block] for i in range(0, len(data), block)]
    assert _long_records_in(blocks, sep, expected) == _has_long_record(text, sep, expected)


@pytest.mark.parametrize(
    "text, long",
    [
        ('a,b\n"1,2",3\n', False),  # a separator inside quotes
        ('a,b\n"1\n,2",3\n', False),  # and a line break
        ("a,b\n1,2,3", True),  # the last record, without a line break
        ("a,b\n1,2\n3,4,5\n", True),
        ('a,b\n"x",""""\n', False),  # doubled quotes
    ],
)
def test_long_record_cases_in_every_block_size(text, long):
    data = text.encode()
    for block in range(1, len(data) + 1):
        blocks = [data[i : i + block] for i in range(0, len(data), block)]
        assert _long_records_in(blocks, ",", 2) == long == _has_long_record(text, ",", 2)


def test_a_column_parsed_as_booleans_gives_its_marks(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("success,other\nTrue,yes\nFalse,no\nTRUE,1\n", encoding="utf-8")
    table = read_table(path)
    assert table.frame["success"].dtype == bool
    np.testing.assert_array_equal(table.boolean("success"), [True, False, True])
    np.testing.assert_array_equal(table.boolean("other"), [True, False, True])


def test_marks_that_are_not_yes_or_no_are_refused_at_their_row(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("success\nTrue\n\nFalse\nmaybe\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"row 5, column 'success': 'maybe' is not a yes/no mark"):
        read_table(path).boolean("success")
    nullable = table_from_frame(pd.DataFrame({"success": pd.array([True, None, False], dtype="boolean"), "n": [1, 2, 3]}))
    with pytest.raises(InputError, match=r"DataFrame, row 1, column 'success': '<NA>' is not a yes/no mark"):
        nullable.boolean("success")


@settings(max_examples=2000, deadline=None)
@given(text=st.text(alphabet="ab\n\r", max_size=40), count=st.integers(1, 12))
@pytest.mark.slow
def test_the_first_lines_are_those_of_a_split(text, count):
    assert _first_lines(text, count) == text.split("\n", count)[:count]
