"""The refusals of one bad record (``Table.refuse_where``): each reader names the file row and
column of the first bad record with its message, for every check that goes through it.

The messages are those the readers gave before the checks shared one method (each check had its
own ``np.flatnonzero`` and ``raise``); this test passed on that code too."""

import re

import pytest

from tromplab.circuit import reconcile
from tromplab.cli import main
from tromplab.curves.ranking import read_f_table
from tromplab.density import read_density
from tromplab.density.washability import read_washability
from tromplab.errors import InputError
from tromplab.loading.lab import read_lab
from tromplab.trend import read_surveys

from .conftest import write

TRACERS = "test,density,placed,sinks,floats\nt,1.3,30,1,28\n"
SIZED_TRACERS = "test,size_lower_mm,size_upper_mm,density,placed,sinks,floats\n"
FLOAT_SINK = "test,density_lower,density_upper,floats_pct,sinks_pct"
LAB = "experiment,size_lower_um,size_upper_um,feed_pct,fine_pct,coarse_pct,fine_yield\n"
CYCLONE = "stream,from,to,product\nfeed,,cyclone,\noverflow,cyclone,,fine\nunderflow,cyclone,,coarse\n"
SURVEY_CLASSES = "overflow,100,,0.1\noverflow,0,100,0.9\nunderflow,100,,0.7\nunderflow,0,100,0.3\n"
SURVEY = "stream,size_lower_um,size_upper_um,retained_frac\n"


def _survey(tmp_path, text):
    return reconcile(write(tmp_path, CYCLONE, "sheet.csv"), write(tmp_path, text, "survey.csv"))


READERS = {
    "density": lambda tmp_path, text: read_density(write(tmp_path, text, "density.csv")),
    "washability": lambda tmp_path, text: read_washability(write(tmp_path, text, "washability.csv")),
    "lab": lambda tmp_path, text: read_lab(write(tmp_path, text, "lab.csv")),
    "F table": lambda tmp_path, text: read_f_table(write(tmp_path, text, "f.csv")),
    "trend": lambda tmp_path, text: read_surveys(write(tmp_path, text, "trend.csv")),
    "survey": _survey,
}

CASES = [
    ("density", TRACERS + "t,1.4,30,-1,15\n", "row 3, column 'sinks': negative count -1"),
    ("density", TRACERS + "t,1.4,30,2000000000,15\n",
     "row 3, column 'sinks': count 2e+09 is more than 1,000,000,000 tracers: a mistyped value?"),
    ("density", TRACERS + "t,1.4,30,1.5,15\n", "row 3, column 'sinks': count 1.5 is not a whole number of tracers"),
    ("density", TRACERS + "t,1.4,30,20,15\n", "row 3, column 'placed': sinks + floats = 35 is more than the 30 tracers placed"),
    ("density", TRACERS + "t,30.4,30,14,15\n",
     "row 3, column 'density': relative density 30.4 outside 0.5..25 (g/cm3, water = 1)"),
    ("density", TRACERS + ",1.4,30,14,15\n", "row 3, column 'test': test name is blank"),
    ("density", SIZED_TRACERS + "t,-2,4,1.3,30,1,28\n",
     "row 2, column 'size_lower_mm': a size bound must be positive (a finest fraction's lower bound may be 0 or blank)"),
    ("density", SIZED_TRACERS + "t,4,2,1.3,30,1,28\n", "row 2, column 'size_lower_mm': size_lower 4 is not below size_upper 2"),
    ("density", f"{FLOAT_SINK}\nt,,1.3,50,10\nt,1.4,1.35,30,30\nt,1.4,,20,60\n",
     "row 3, column 'density_lower': lower bound 1.4 is not below the upper bound 1.35"),
    ("density", f"{FLOAT_SINK}\nt,,1.3,50,10\nt,,,30,30\nt,1.4,,20,60\n",
     "row 3, column 'density_lower': the fraction has neither a lower nor an upper bound"),
    ("density", f"{FLOAT_SINK},floats_yield\nt,,1.3,60,10,0.5\nt,1.3,1.4,30,30,1.5\nt,1.4,,10,60,0.5\n",
     "row 3, column 'floats_yield': floats yield 1.5 outside (0, 1) (a share of the feed, not per cent)"),
    ("washability", "test,density_lower,density_upper,mass_pct,ash_pct\nw,,1.3,60,4\n,1.3,,40,30\n",
     "row 3, column 'test': test name is blank"),
    ("lab", LAB + "a,-100,200,50,80,20,0.5\n",
     "row 2, column 'size_lower_um': class bounds must be positive (a pan's lower bound may be 0 or blank)"),
    ("lab", LAB + "a,300,200,50,80,20,0.5\n", "row 2, column 'size_lower_um': lower bound 300 is not below the upper bound 200"),
    ("lab", LAB + "a,100,200,50,80,20,0.5\na,,,50,20,80,0.5\n",
     "row 3, column 'size_lower_um': the class has neither a lower nor an upper bound"),
    ("lab", LAB + "a,100,200,-50,80,20,0.5\n", "row 2, column 'feed_pct': negative amount -50"),
    ("lab", LAB + "a,100,200,150,80,20,0.5\n", "row 2, column 'feed_pct': amount 150 is above 101.5, more than the whole stream"),
    ("lab", LAB + "a,200,300,30,50,10,0.5\na,100,200,30,30,30,1.5\na,0,100,40,20,60,0.5\n",
     "row 3, column 'fine_yield': yield 1.5 outside (0, 1)"),
    ("lab", "experiment,size_lower_um,size_upper_um,size_representative_um,feed_pct,fine_pct,coarse_pct,fine_yield\n"
     "a,200,300,,30,50,10,0.5\na,100,200,300,30,30,30,0.5\na,0,100,,40,20,60,0.5\n",
     "row 3, column 'size_representative_um': representative size 300 outside its class 100-200"),
    ("lab", "experiment,size_um,feed_pct,fine_pct,coarse_pct,fine_yield\na,-100,50,80,20,0.5\n",
     "row 2, column 'size_um': sieve size must be positive"),
    ("F table", "experiment,equation,F,n\n1,3,-5.0,5\n", "row 2, column 'F': F must be a number >= 0, got -5"),
    ("F table", "experiment,equation,F,n\n1,3,5.0,5\n1,3,6.0,5\n",
     "row 3, column 'equation': the same experiment and equation appear twice"),
    ("F table", "experiment,equation,F,n\n1,3,5.0,5\n,4,6.0,5\n", "row 3, column 'experiment': experiment name is blank"),
    ("F table", "experiment,equation,F,n\n1,3,5.0,5\n1,,6.0,5\n", "row 3, column 'equation': equation is blank"),
    ("trend", "survey,date,size,partition_fine\nS1,2025-01-06,38,0.8\nS2,notadate,38,0.8\n",
     "row 3, column 'date': 'notadate' is not a date (use YYYY-MM-DD)"),
    ("survey", "stream,size_class,retained_frac\nfeed,+100,0.4\nfeed,-100,0.6\nunderflow,+0,\n",
     "row 4, column 'size_class': the class has neither a lower nor an upper bound"),
    ("survey", "stream,size_class,retained_frac\nfeed,+100,0.4\nfeed,-100+200,0.6\n",
     "row 3, column 'size_class': class '-100+200': the lower bound is not below the upper bound"),
    ("survey", SURVEY + "feed,100,,0.4\nfeed,-5,100,0.6\n",
     "row 3, column 'size_lower_um': class bounds must be positive (a pan's lower bound may be 0 or blank)"),
    ("survey", SURVEY + "feed,100,,0.4\nfeed,0,0,0.6\n", "row 3, column 'size_upper_um': an upper bound must be positive"),
    ("survey", SURVEY + "feed,100,,0.4\nfeed,200,100,0.6\n",
     "row 3, column 'size_lower_um': lower bound 200 is not below the upper bound 100"),
    ("survey", SURVEY + "feed,100,,0.4\nfeed,,,0.6\n" + SURVEY_CLASSES,
     "row 3, column 'retained_frac': a retained value without a size class"),
    ("survey", SURVEY.replace("\n", ",relative_error\n") + "feed,100,,0.4,-0.1\nfeed,0,100,0.6,\n",
     "row 2, column 'relative_error': relative_error must not be negative"),
    ("survey", SURVEY.replace("\n", ",solids_flow\n") + "feed,100,,0.4,-100\nfeed,0,100,0.6,\n",
     "row 2, column 'solids_flow': negative solids flow -100"),
    ("survey", SURVEY.replace("\n", ",solids_flow,solids_flow_sd\n") + "feed,100,,0.4,100,-1\nfeed,0,100,0.6,,\n",
     "row 2, column 'solids_flow_sd': a standard deviation must not be negative"),
]  # fmt: skip


@pytest.mark.parametrize("reader, text, where", CASES)
def test_the_first_bad_record_is_named_by_row_and_column(tmp_path, reader, text, where):
    with pytest.raises(InputError, match=re.escape(f", {where}")):
        READERS[reader](tmp_path, text)


@pytest.mark.parametrize(
    "rows, where",
    [
        ("0,0.1\n50,0.5\n", "row 2, column 'step': must be at least one step"),
        ("25,0.1\n5000000,0.5\n", "row 3, column 'step': 5e+06 steps: at most 1,000,000 are simulated"),
        ("25,0.1\n50,1.5\n", "row 3, column 'extraction': extraction 1.5 outside 0..1"),
    ],
)
def test_layer_fit_names_the_first_bad_step_or_extraction(tmp_path, capsys, rows, where):
    data = write(tmp_path, "step,extraction\n" + rows + "75,0.6\n100,0.7\n", "layer.csv")
    assert main(["layer", "fit", str(data), "-o", str(tmp_path / "out")]) == 1
    assert f"layer.csv, {where}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
