"""The HTML report is well formed and holds every section; the Markdown twin too."""

from html.parser import HTMLParser

import pandas as pd
import pytest

from tromplab.cli import main
from tromplab.output.report import SECTIONS

from .conftest import DATASETS

VOID = {"meta", "img", "br", "hr", "link", "input", "wbr"}  # the void elements of HTML


class TagChecker(HTMLParser):
    """Checks that every non-void tag is closed in order, and collects section ids and images."""

    def __init__(self):
        super().__init__()
        self.stack, self.errors, self.sections, self.images = [], [], [], 0

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "section":
            self.sections.append(attrs.get("id"))
        if tag == "img":
            self.images += attrs.get("src", "").startswith("data:image/png;base64,")
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if tag in VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"unexpected </{tag}> with open {self.stack[-3:]}")
        else:
            self.stack.pop()


@pytest.mark.slow
def test_report_from_lab_data(tmp_path, capsys):
    output = tmp_path / "out" / "report.html"
    assert main(["report", str(DATASETS / "double_deck_screen_decks_lab.csv"), "-o", str(output), "--size-unit", "mm"]) == 0
    text = output.read_text()
    checker = TagChecker()
    checker.feed(text)
    checker.close()
    assert checker.errors == [] and checker.stack == []
    assert checker.sections == list(SECTIONS)
    assert checker.images == 6  # two curves, two residual plots, heatmap, ranking
    for needle in ("Fine yield 0.2639 (column fine_yield)", "deck_65mesh", "F_crit", "profile", "place"):
        assert needle in text
    markdown = (tmp_path / "out" / "report.md").read_text()
    assert markdown.count("\n## ") == len(SECTIONS)
    assert "![Tromp curve, experiment deck_20mesh](report_figures/figure1.png)" in markdown
    assert (tmp_path / "out" / "report_figures" / "figure1.png").stat().st_size > 10_000
    assert not list((tmp_path / "out").glob("*.png"))  # no figure beside the user's files


def test_report_of_points_says_when_a_section_does_not_apply(tmp_path):
    path = tmp_path / "points.csv"
    path.write_text("size,partition_fine\n10,0.97\n20,0.9\n40,0.7\n80,0.35\n160,0.1\n320,0.02\n")
    output = tmp_path / "r.html"
    assert main(["report", str(path), "-o", str(output)]) == 0
    text = output.read_text()
    balance = text.split('<section id="balance">')[1].split("</section>")[0]
    assert "Not applicable to this input." in balance


@pytest.mark.slow
def test_a_large_batch_gets_a_condensed_report_with_its_full_tables_beside_it(tmp_path, monkeypatch):
    """Beyond REPORT_DETAIL_LIMIT experiments the sections show the first ones and the
    flagged ones, the figures an overview, and every row goes to CSV files beside the report."""
    import tromplab.output.report as report_module
    from tromplab._synthetic import synthetic
    from tromplab.workbench import fit_experiments as fit_batch

    monkeypatch.setattr(report_module, "REPORT_DETAIL_LIMIT", 3)
    bench = fit_batch([synthetic(seed, weighted=False) for seed in range(12)], formulas=["plitt", "lognormal"])
    written = bench.write_report(tmp_path / "big.html")
    assert {"big_fits.csv", "big_ranking.csv", "big_averages.csv"} <= set(written)
    assert len(pd.read_csv(written["big_fits.csv"])) == 24  # every fit, not only those shown
    html = written["big.html"].read_text()
    shown = [f"Experiment s{seed}" for seed in range(12) if f"Experiment s{seed}<" in html or f"Experiment s{seed}:" in html]
    assert 3 <= len(shown) <= 6 and "12 experiments: the sections below show the first 3" in html
    assert "Top-ranked fits of all experiments" in html and "across experiments and formulas" not in html


@pytest.mark.slow
def test_the_figures_drawn_by_two_workers_give_the_same_report(tmp_path):
    """tromplab report --jobs draws the per-experiment figures on the workers (in chunks of
    FIGURE_CHUNK experiments): the HTML, with its embedded figures, is the same for 1 and 2."""
    from tromplab._synthetic import synthetic

    rows = [
        pd.DataFrame({"experiment": p.experiment, "size": p.size, "partition_fine": p.partition_fine})
        for p in (synthetic(seed) for seed in range(8))
    ]
    points = tmp_path / "points.csv"
    pd.concat(rows).to_csv(points, index=False)
    pages = []
    for jobs in ("1", "2"):
        out = tmp_path / f"report_{jobs}" / "report.html"
        assert main(["report", str(points), "-o", str(out), "--jobs", jobs, "--formulas", "plitt,lognormal", "-q"]) == 0
        pages.append(out.read_text(encoding="utf-8"))
    assert pages[0] == pages[1] and pages[0].count("<img") >= 16


@pytest.mark.slow
def test_tromplab_report_of_200_experiments(tmp_path):
    """The command on 200 experiments (the F heatmap's labels broke it from
    about 40 on) writes a condensed report with the full tables beside it, and its figures
    stay bounded whatever the batch size."""
    from tromplab._synthetic import synthetic
    from tromplab.output.report import REPORT_DETAIL_LIMIT

    rows = [
        pd.DataFrame({"experiment": p.experiment, "size": p.size, "partition_fine": p.partition_fine})
        for p in (synthetic(seed, weighted=False) for seed in range(200))
    ]
    points = tmp_path / "points.csv"
    pd.concat(rows).to_csv(points, index=False)
    out = tmp_path / "report.html"
    assert main(["report", str(points), "-o", str(out), "--formulas", "plitt,lognormal,rosin_rammler", "-q"]) == 0
    html = out.read_text(encoding="utf-8")
    assert f"200 experiments: the sections below show the first {REPORT_DETAIL_LIMIT}" in html
    assert "Top-ranked fits of all experiments" in html
    drawn = html.count("<figcaption>Tromp curve, experiment")  # the first ones and the flagged ones (at most as many)
    assert REPORT_DETAIL_LIMIT <= drawn <= 2 * REPORT_DETAIL_LIMIT
    assert html.count("<figcaption>Residuals, experiment") == drawn
    fits = pd.read_csv(tmp_path / "report_fits.csv")
    assert len(fits) == 600 and set(fits["experiment"]) == {f"s{seed}" for seed in range(200)}
    assert len(pd.read_csv(tmp_path / "report_ranking.csv")) == 3
