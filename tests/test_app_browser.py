"""``tromplab app`` in a real browser: Playwright for Python drives Debian's Chromium
(/usr/bin/chromium; Playwright's own browser download is not used) against the server started
as a user starts it, ``tromplab app --port P --no-browser``.

Without Chromium or Playwright the tests are skipped, saying so, except where
TROMPLAB_BROWSER_TESTS=required (.ci/run sets it): there their absence fails the run.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pandas as pd
import pytest

from tests.app_support import HOSTILE_NAMES, assert_same_file, points_csv, run_cli, zip_members

CHROMIUM = Path(os.environ.get("TROMPLAB_CHROMIUM", "/usr/bin/chromium"))
DATASETS = Path(__file__).resolve().parent.parent / "datasets"
#: A stream named as markup that would run a script if the page or plotly read it as HTML.
HOSTILE_STREAM = "<img src=x onerror=window.__xss='stream'>"
REQUIRED = os.environ.get("TROMPLAB_BROWSER_TESTS") == "required"
#: Chromium's flags on a machine without a screen or a network beyond loopback: no sandbox as
#: root, no background connections (refused here, and each would be retried).
CHROMIUM_FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync"]  # fmt: skip
pytestmark = pytest.mark.slow


def _missing() -> str:
    import importlib.util

    if not CHROMIUM.exists():
        return f"Chromium not found at {CHROMIUM} (apt-get install chromium)"
    for module, what in (("playwright", "Playwright for Python"), ("starlette", "the app extra"), ("uvicorn", "the app extra")):
        if importlib.util.find_spec(module) is None:
            return f"{what} is not installed (pip install -e '.[test]')"
    return ""


@pytest.fixture(scope="module")
def server():
    missing = _missing()
    if missing:
        if REQUIRED:
            pytest.fail(f"browser tests are required here (TROMPLAB_BROWSER_TESTS=required): {missing}")
        pytest.skip(missing)
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    process = subprocess.Popen([sys.executable, "-m", "tromplab", "app", "--port", str(port), "--no-browser"],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)  # fmt: skip
    address = f"http://127.0.0.1:{port}/"
    ends = time.monotonic() + 60
    while True:
        try:
            urllib.request.urlopen(address, timeout=2).read()
            break
        except OSError:
            if process.poll() is not None or time.monotonic() > ends:
                process.kill()
                pytest.fail(f"tromplab app did not start: {process.communicate()[0]}")
            time.sleep(0.3)
    yield address, process
    process.terminate()
    process.wait(30)


@pytest.fixture(scope="module")
def browser(server):
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_FLAGS)
        yield browser
        browser.close()


@pytest.fixture
def page(browser, server):
    context = browser.new_context(accept_downloads=True, viewport={"width": 1280, "height": 1000})
    page = context.new_page()
    page.dialogs = []
    page.on("dialog", lambda dialog: (page.dialogs.append(dialog.message), dialog.dismiss()))
    page.goto(server[0])
    yield page
    context.close()


def expect(locator):
    from playwright.sync_api import expect

    return expect(locator)


def drop(page, name: str, text: str) -> None:
    page.set_input_files("#file-input", files=[{"name": name, "mimeType": "text/csv", "buffer": text.encode()}])
    expect(page.locator("#file-name")).to_have_text(name)  # this file's answer is in: its form is built
    page.get_by_role("button", name="Fit").wait_for(state="visible")


def drop_files(page, files: dict[str, str]) -> None:
    """Drop several files at once (a circuit's flowsheet and survey) through the page's file input."""
    page.set_input_files(
        "#file-input", files=[{"name": name, "mimeType": "text/csv", "buffer": text.encode()} for name, text in files.items()]
    )
    expect(page.locator("#file-name")).to_have_text(list(files)[-1])
    page.locator("#run-button").wait_for(state="visible")


def fit(page) -> None:
    page.get_by_role("button", name="Fit").click()
    page.locator("#results-section").wait_for(state="visible", timeout=120_000)


def command_results(folder: Path, name: str, text: str, options: list[str]) -> Path:
    """The files ``tromplab fit`` and ``tromplab report`` write for ``name`` in ``folder``."""
    folder.mkdir()
    (folder / name).write_text(text)
    assert run_cli(folder, ["fit", name, "-o", "results", "--excel", *options])[0] == 0
    assert run_cli(folder, ["report", name, "-o", "report.html", *options])[0] == 0  # the fit's --ci is the report's level
    return folder


def best_d50(fits: pd.DataFrame, experiment: str) -> tuple[str, float]:
    """The command's best fit of an experiment: the top rank, the lowest sum of squares among ties."""
    own = fits[fits["experiment"] == experiment]
    top = own[own["rank"] == own["rank"].min()].sort_values("ssr")
    return top["formula"].iloc[0], float(top["d50"].iloc[0])


def test_the_server_listens_on_loopback_only(server):
    psutil = pytest.importorskip("psutil")
    listening = [c for c in psutil.Process(server[1].pid).net_connections(kind="inet") if c.status == psutil.CONN_LISTEN]
    assert listening and {c.laddr.ip for c in listening} == {"127.0.0.1"}


def test_upload_fit_and_see_the_ranking_with_the_command_s_cut_and_no_script_run(page, tmp_path):
    text = points_csv()
    drop(page, "<script>alert(1)</script>.csv", text)
    assert page.locator("#file-name").inner_text() == "<script>alert(1)</script>.csv"  # shown as written
    assert page.locator("#file-kind").inner_text() == "(Tromp points)"
    fit(page)
    assert "plitt" in page.locator("#ranking-table").inner_text()
    assert "plitt" in page.locator("#fits-table").inner_text()
    fits = pd.read_csv(command_results(tmp_path / "cli", "hostile points.csv", text, []) / "results" / "fits.csv")
    shown = page.locator("#best-list li").all_inner_texts()
    for experiment, line in zip(HOSTILE_NAMES, shown):
        formula, d50 = best_d50(fits, experiment)
        assert line.startswith(f"{experiment}: best formula {formula}, cut size d50 = {float(f'{d50:.3g}'):g}")
    # the names are shown as written, and none of them became markup or ran
    assert page.locator("#experiment-select option").all_inner_texts() == list(HOSTILE_NAMES)
    assert page.evaluate("window.__xss") is None and page.dialogs == []
    assert page.locator("img[src='x']").count() == 0 and page.locator("main script").count() == 0
    assert page.locator("#figure .gtitle").text_content() == HOSTILE_NAMES[0]  # the figure title, as written


def test_change_an_option_fit_again_and_download_what_the_command_writes(page, tmp_path):
    lab = (Path(__file__).resolve().parent.parent / "datasets" / "double_deck_screen_decks_lab.csv").read_text()
    drop(page, "lab.csv", lab)
    fit(page)
    page.fill("#option-size_unit", "mm")
    page.select_option("#option-rank_by", "aicc")
    page.fill("#option-ci", "0.9")
    fit(page)
    page.locator("#intervals-table th", has_text="d50_low").wait_for()
    assert "d50 = 0.886 mm" in page.locator("#best-list").inner_text()
    assert page.locator("#figure .g-xtitle").text_content() == "size (mm)"
    expected = command_results(tmp_path / "cli", "lab.csv", lab, ["--size-unit=mm", "--rank-by=aicc", "--ci=0.9"])
    with page.expect_download() as download:
        page.click("#download-zip")
    members = zip_members(Path(download.value.path()).read_bytes())
    assert sorted(members) == sorted(p.relative_to(expected).as_posix() for p in (expected / "results").rglob("*") if p.is_file())
    for name, data in members.items():
        assert_same_file(data, expected / name)
    for link, name in (("#download-report", "report.html"), ("#download-xlsx", "results/results.xlsx")):
        with page.expect_download() as download:
            page.click(link)
        assert_same_file(Path(download.value.path()).read_bytes(), expected / name)


def test_density_tracers_fitted_on_the_page_as_tromplab_density_fit_fits_them(page, tmp_path):
    name = "density_tracers_dmc_by_size_synthetic.csv"
    tracers = (Path(__file__).resolve().parent.parent / "datasets" / name).read_text()
    drop(page, name, tracers)
    assert page.locator("#options-command").inner_text() == "tromplab density fit"
    fit(page)
    (tmp_path / name).write_text(tracers)
    assert run_cli(tmp_path, ["density", "fit", name, "-o", "results", "--excel", "--report"])[0] == 0
    fits = pd.read_csv(tmp_path / "results" / "fits.csv")
    best = fits[fits["rank"] == 1]
    expected = [f"best curve {row.curve}, rho50 = {float(f'{row.rho50:.3g}'):g} g/cm3" for row in best.itertuples()]
    shown = page.locator("#best-list li").all_inner_texts()
    assert len(shown) == len(expected) == 4 and all(want in line for want, line in zip(expected, shown))
    with page.expect_download() as download:
        page.click("#download-report")
    assert_same_file(Path(download.value.path()).read_bytes(), tmp_path / "results" / "report.html")


def test_a_bad_option_and_a_bad_file_show_the_command_line_s_message(page, tmp_path):
    drop(page, "points.csv", points_csv(("A",)))
    page.fill("#option-alpha", "2")
    page.get_by_role("button", name="Fit").click()
    error = page.locator("#run-error")
    error.wait_for(state="visible")
    assert (
        error.inner_text()
        == "tromplab fit: error: argument --alpha: must lie strictly between 0 and 1, got 2\n  see 'tromplab fit -h' for the options"
    )
    bad = points_csv(("A",)).replace("156.0,0.442", "156.0,oops")
    drop(page, "bad.csv", bad)
    page.get_by_role("button", name="Fit").click()
    (tmp_path / "bad.csv").write_text(bad)
    code, said = run_cli(tmp_path, ["fit", "bad.csv", "-o", "results", "--excel"])
    assert code == 1 and "row" in said
    expect(error).to_have_text(said.strip(), timeout=60_000)


def test_the_ranked_table_sorts_and_shows_tied_ranks(page):
    lab = (Path(__file__).resolve().parent.parent / "datasets" / "double_deck_screen_decks_lab.csv").read_text()
    drop(page, "lab.csv", lab)
    fit(page)
    page.select_option("#experiment-select", label="deck_65mesh")
    assert page.locator("#fits-table .tie").count() == 8  # eight formulas share rank 4.5 (their F agree to 1e-4)
    page.locator("#fits-table th", has_text="formula").first.click()
    formulas = page.locator("#fits-table tbody tr td:nth-child(3)").all_inner_texts()
    assert formulas == sorted(formulas)


def test_a_run_can_be_cancelled_from_the_page(page):
    trend = (Path(__file__).resolve().parent.parent / "datasets" / "classifier_trend_surveys.csv").read_text()
    drop(page, "trend.csv", trend)
    page.fill("#option-bootstrap", "3000")
    page.get_by_role("button", name="Fit").click()
    page.locator("#progress-box").wait_for(state="visible")
    page.get_by_role("button", name="Cancel").click()
    expect(page.locator("#run-error")).to_have_text("Cancelled: nothing was kept.")
    assert page.get_by_role("button", name="Fit").is_enabled()


def test_screenshots_of_the_page_for_the_docs(page, tmp_path):
    """Not a check: the pictures of docs/app.md, taken when TROMPLAB_APP_SCREENSHOTS names a folder."""
    folder = os.environ.get("TROMPLAB_APP_SCREENSHOTS")
    if not folder:
        pytest.skip("set TROMPLAB_APP_SCREENSHOTS=docs to take the docs' screenshots")
    lab = (Path(__file__).resolve().parent.parent / "datasets" / "double_deck_screen_decks_lab.csv").read_text()
    drop(page, "double_deck_screen_decks_lab.csv", lab)
    page.fill("#option-size_unit", "mm")
    page.fill("#option-ci", "0.95")
    page.locator("#table-section").screenshot(path=str(Path(folder) / "app_table.png"))
    fit(page)
    page.wait_for_timeout(500)
    page.locator("#results-section").screenshot(path=str(Path(folder) / "app_results.png"))


def test_a_circuit_from_its_two_files_shows_the_flowsheet_and_its_balance_and_no_script_runs(page, tmp_path):
    flowsheet = (DATASETS / "circuit_example_flowsheet.csv").read_text().replace("cyclone_overflow", HOSTILE_STREAM)
    survey = (DATASETS / "circuit_example_survey.csv").read_text().replace("cyclone_overflow", HOSTILE_STREAM)
    drop_files(page, {"flowsheet.csv": flowsheet, "survey.csv": survey})
    expect(page.locator("#circuit-pair")).to_have_text("Circuit: flowsheet flowsheet.csv, survey survey.csv")
    assert page.locator("#options-command").inner_text() == "tromplab circuit"
    page.get_by_role("button", name="Run").click()
    page.locator("#circuit-results").wait_for(state="visible", timeout=120_000)
    (tmp_path / "flowsheet.csv").write_text(flowsheet)
    (tmp_path / "survey.csv").write_text(survey)
    assert run_cli(tmp_path, ["circuit", "flowsheet.csv", "survey.csv", "-o", "results"])[0] == 0
    flows = pd.read_csv(tmp_path / "results" / "flows.csv")
    # the figure: a label per stream with its reconciled flow, the units, the hostile name as written
    labels = page.locator("#flowsheet .textpoint").all_text_contents()
    for row in flows.itertuples():
        assert any(label.startswith(row.stream) and f"{float(f'{row.reconciled:.4g}'):g}" in label for label in labels), (
            row.stream
        )
    assert {"top_deck", "bottom_deck", "mill", "cyclone"} <= set(labels)
    # the balance table, flows.csv, sortable like every table of the page
    table = page.locator("#circuit-table")
    assert page.locator("#circuit-table-select").input_value() == "0" and HOSTILE_STREAM in table.inner_text()
    assert table.locator("tbody tr").count() == len(flows)
    page.locator("#circuit-table th", has_text="reconciled_sd").click()
    shown = [float(text) for text in page.locator("#circuit-table tbody tr td:nth-child(8)").all_inner_texts()]
    assert shown == sorted(shown)
    page.select_option("#circuit-table-select", label="design.csv")
    assert "solids flow" in page.locator("#circuit-table").inner_text()
    assert page.evaluate("window.__xss") is None and page.dialogs == []
    assert page.locator("img[src='x']").count() == 0
    with page.expect_download() as download:
        page.click("#download-zip")
    members = zip_members(Path(download.value.path()).read_bytes())
    assert_same_file(members["results/flows.csv"], tmp_path / "results" / "flows.csv")
    assert page.locator("#download-report").is_hidden() and page.locator("#download-xlsx").is_hidden()


def test_circuit_design_of_a_flowsheet_alone_shows_the_ranked_candidates_on_the_page(page, tmp_path):
    flowsheet = (DATASETS / "circuit_example_flowsheet.csv").read_text().replace("cyclone_overflow", HOSTILE_STREAM)
    drop_files(page, {"flowsheet.csv": flowsheet})
    expect(page.locator("#circuit-pair")).to_have_text("Circuit: flowsheet flowsheet.csv, survey (drop it too)")
    assert page.locator("#command-select option").all_inner_texts() == ["tromplab circuit", "tromplab circuit design"]
    page.select_option("#command-select", "tromplab circuit design")
    expect(page.locator("#options-command")).to_have_text("tromplab circuit design")
    page.get_by_role("button", name="Run").click()
    page.locator("#circuit-results").wait_for(state="visible", timeout=120_000)
    (tmp_path / "flowsheet.csv").write_text(flowsheet)
    assert run_cli(tmp_path, ["circuit", "design", "flowsheet.csv", "-o", "results"])[0] == 0
    design = pd.read_csv(tmp_path / "results" / "design.csv", keep_default_na=False)
    assert page.locator("#circuit-table-select option").all_inner_texts() == [
        "design.csv", "observability.csv", "simulated_survey.csv"
    ]  # fmt: skip
    table = page.locator("#circuit-table")
    assert table.locator("tbody tr").count() == min(len(design), 500)
    first = table.locator("tbody tr").first.locator("td").all_inner_texts()
    assert first[:2] == [str(value) for value in design.iloc[0, :2]]  # the best candidate first, as the file ranks it
    summary = (tmp_path / "results" / "summary.txt").read_text(encoding="utf-8")
    assert page.locator("#circuit-summary").inner_text().split() == summary.split()
    labels = page.locator("#flowsheet .textpoint").all_text_contents()
    assert {"top_deck", "bottom_deck", "mill", "cyclone"} <= set(labels)
    expect(page.locator("#flowsheet-heading")).to_contain_text("a survey simulated from the flowsheet")
    assert page.evaluate("window.__xss") is None and page.dialogs == [] and page.locator("img[src='x']").count() == 0
    with page.expect_download() as download:
        page.click("#download-zip")
    members = zip_members(Path(download.value.path()).read_bytes())
    assert_same_file(members["results/design.csv"], tmp_path / "results" / "design.csv")


def test_dated_surveys_charted_by_tromplab_trend_on_the_page(page, tmp_path):
    trend = (DATASETS / "classifier_trend_surveys.csv").read_text()
    drop(page, "surveys.csv", trend)
    assert page.locator("#command-select option").all_inner_texts() == ["tromplab fit", "tromplab trend"]
    page.select_option("#command-select", "tromplab trend")
    expect(page.locator("#run-button")).to_have_text("Run")
    page.fill("#option-size_unit", "um")
    page.get_by_role("button", name="Run").click()
    page.locator("#trend-results").wait_for(state="visible", timeout=180_000)
    (tmp_path / "surveys.csv").write_text(trend)
    assert run_cli(tmp_path, ["trend", "surveys.csv", "-o", "results", "--size-unit=um"])[0] == 0
    charted = pd.read_csv(tmp_path / "results" / "trend.csv")
    quantities = list(dict.fromkeys(charted["quantity"]))
    for quantity in quantities:  # one interactive chart per quantity, drawn by plotly
        page.locator(f"#trend-chart-{quantity} .main-svg").first.wait_for()
    assert page.locator("#trend-charts > div").count() == len(quantities)
    flags = pd.read_csv(tmp_path / "results" / "trend_surveys.csv")
    points = ", ".join(flags.loc[flags["change_point"], "survey"]) or "none"
    assert f"Change points: {points}." in page.locator("#trend-summary").inner_text()
    assert page.locator("#trend-flags tbody tr").count() == len(flags)
    with page.expect_download() as download:
        page.click("#download-trend-report")
    assert_same_file(Path(download.value.path()).read_bytes(), tmp_path / "results" / "trend_report.html")


def test_screenshots_of_the_circuit_and_trend_views_for_the_docs(page):
    """Not a check: the pictures of the circuit and trend views in docs/app.md (TROMPLAB_APP_SCREENSHOTS)."""
    folder = os.environ.get("TROMPLAB_APP_SCREENSHOTS")
    if not folder:
        pytest.skip("set TROMPLAB_APP_SCREENSHOTS=docs to take the docs' screenshots")
    page.select_option("#example-select", "circuit_example")
    page.click("#example-button")
    expect(page.locator("#pair-survey")).to_have_text("circuit_example_survey.csv")
    page.get_by_role("button", name="Run").click()
    page.locator("#circuit-results").wait_for(state="visible", timeout=120_000)
    page.wait_for_timeout(500)
    page.locator("#results-section").screenshot(path=str(Path(folder) / "app_circuit.png"))
    page.select_option("#example-select", "classifier_trend_surveys.csv")
    page.click("#example-button")
    page.select_option("#command-select", "tromplab trend")
    page.fill("#option-size_unit", "um")
    page.get_by_role("button", name="Run").click()
    page.locator("#trend-results").wait_for(state="visible", timeout=180_000)
    page.wait_for_timeout(500)
    page.locator("#trend-charts").screenshot(path=str(Path(folder) / "app_trend.png"))
