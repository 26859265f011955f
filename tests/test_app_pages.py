"""``tromplab app`` runs ``tromplab circuit`` (a flowsheet and a survey, two files) and
``tromplab trend`` (dated surveys), and its ``report.html`` comes from the page's one fit:
through Starlette's test client, each download compared byte for byte with what the command
writes for the same files and options, each bad file answered with the command line's message.
The same pages in a real browser: test_app_browser.py."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

pytest.importorskip("starlette", reason="the app extra is not installed: pip install -e '.[test]'")
pytest.importorskip("httpx", reason="Starlette's test client needs httpx: pip install -e '.[test]'")

from starlette.testclient import TestClient  # noqa: E402

from tests.app_support import assert_same_file, run_cli, wait_for_run, zip_members  # noqa: E402
from tests.conftest import DATASETS  # noqa: E402
from tromplab.app import jobs  # noqa: E402
from tromplab.app.server import create_app  # noqa: E402

PAGE = {"x-tromplab-page": "1"}
FLOWSHEET, SURVEY = DATASETS / "circuit_example_flowsheet.csv", DATASETS / "circuit_example_survey.csv"
TREND = DATASETS / "classifier_trend_surveys.csv"


@pytest.fixture
def client():
    with TestClient(create_app(), base_url="http://127.0.0.1", headers=PAGE) as client:
        client.get("/api/session")
        yield client


def upload(client, name: str, data: bytes) -> dict:
    return client.post("/api/upload", params={"name": name}, content=data).json()


def run(client, options: dict | None = None, command: str | None = None) -> dict:
    started = client.post("/api/run", json={"options": options or {}, "command": command})
    assert started.status_code == 200, started.text
    return wait_for_run(client, timeout=300)


def assert_folder_is_the_command_s(client, folder: Path) -> None:
    """The zip offered holds the files of ``folder/results``, byte for byte."""
    members = zip_members(client.get("/api/download/results.zip").content)
    written = sorted(p.relative_to(folder).as_posix() for p in (folder / "results").rglob("*") if p.is_file())
    assert sorted(members) == written
    for name, data in members.items():
        assert_same_file(data, folder / name)


# -- circuit: two files -----------------------------------------------------------------------------
def test_a_circuit_needs_its_flowsheet_and_its_survey(client):
    assert upload(client, "flowsheet.csv", FLOWSHEET.read_bytes())["kind"]["kind"] == "flowsheet"
    refused = client.post("/api/run", json={"options": {}})
    assert refused.status_code == 400
    assert refused.json()["error"] == "tromplab circuit reads a flowsheet and a survey: drop the survey too"
    assert upload(client, "flowsheet.csv", SURVEY.read_bytes())["circuit"] == {
        "flowsheet": "flowsheet.csv",
        "survey": "flowsheet.csv",
    }
    assert "both named flowsheet.csv" in client.post("/api/run", json={"options": {}}).json()["error"]


@pytest.mark.slow
def test_a_circuit_is_reconciled_and_downloaded_as_tromplab_circuit_writes_it(client, tmp_path):
    upload(client, SURVEY.name, SURVEY.read_bytes())  # the survey first: the pair is made in either order
    upload(client, FLOWSHEET.name, FLOWSHEET.read_bytes())
    state = run(client, {"alpha": "0.1", "relative_error": "0.06", "fit": True})
    assert state["state"] == "done", state
    assert state["downloads"] == ["results.zip"]
    for path in (FLOWSHEET, SURVEY):
        shutil.copyfile(path, tmp_path / path.name)
    arguments = ["circuit", FLOWSHEET.name, SURVEY.name, "-o", "results", "--alpha=0.1", "--relative-error=0.06", "--fit"]
    assert run_cli(tmp_path, arguments)[0] == 0
    assert_folder_is_the_command_s(client, tmp_path)
    page = state["page"]
    # the figure's flows are those of flows.csv; its streams join the flowsheet's nodes
    flows = pd.read_csv(tmp_path / "results" / "flows.csv").set_index("stream")
    figure = page["flowsheet"]
    assert [stream["name"] for stream in figure["streams"]] == list(flows.index)
    for stream in figure["streams"]:
        assert stream["reconciled"] == pytest.approx(flows.loc[stream["name"], "reconciled"], rel=1e-12)
        assert stream["reconciled_sd"] == pytest.approx(flows.loc[stream["name"], "reconciled_sd"], rel=1e-12)
    nodes = {node["name"]: (node["x"], node["y"]) for node in figure["nodes"]}
    assert set(nodes) == {"top_deck", "bottom_deck", "mill", "cyclone"}
    underflow = next(stream for stream in figure["streams"] if stream["name"] == "cyclone_underflow")
    assert (underflow["path"]["x"][0], underflow["path"]["y"][0]) == nodes["cyclone"]
    assert (underflow["path"]["x"][-1], underflow["path"]["y"][-1]) == nodes["mill"]
    assert len(underflow["path"]["x"]) == 4  # a recycle, drawn back below the units
    shown = {table["name"]: table for table in page["tables"]}
    assert list(shown) == ["flows.csv", "chi_square.csv", "gross_errors.csv", "adjustments.csv", "elimination.csv",
                           "partition.csv", "design.csv", "worth.csv", "fits.csv", "ranking.csv"]  # fmt: skip
    design = pd.read_csv(tmp_path / "results" / "design.csv")
    assert shown["design.csv"]["rows_in_file"] == len(design)
    assert shown["design.csv"]["table"]["columns"] == list(design.columns)
    summary = (tmp_path / "results" / "summary.txt").read_text(encoding="utf-8").splitlines()
    assert page["summary"] == summary


def test_a_suspected_gross_error_is_marked_on_its_stream(client, tmp_path):
    # five percentage points of the feed's -4750+2360 class written in the class above it: the
    # analysis still sums to 100 %, the balances of the two decks cannot hold it
    survey = SURVEY.read_text()
    for written, swapped in (("4750.0,9500.0,21.45", "4750.0,9500.0,26.45"), ("2360.0,4750.0,19.51", "2360.0,4750.0,14.51")):
        assert f"screen_feed,{written}" in survey
        survey = survey.replace(f"screen_feed,{written}", f"screen_feed,{swapped}")
    upload(client, "flowsheet.csv", FLOWSHEET.read_bytes())
    upload(client, "survey.csv", survey.encode())
    state = run(client)
    assert state["state"] == "done", state
    (tmp_path / "flowsheet.csv").write_bytes(FLOWSHEET.read_bytes())
    (tmp_path / "survey.csv").write_text(survey)
    assert run_cli(tmp_path, ["circuit", "flowsheet.csv", "survey.csv", "-o", "results"])[0] == 0
    suspects = pd.read_csv(tmp_path / "results" / "gross_errors.csv")
    assert len(suspects) and "screen_feed" in set(suspects["stream"])
    marked = {stream["name"]: stream["suspects"] for stream in state["page"]["flowsheet"]["streams"] if stream["suspects"]}
    assert set(marked) == set(suspects["stream"])
    assert [s["measurement"] for s in marked["screen_feed"]] == list(
        suspects.loc[suspects["stream"] == "screen_feed", "measurement"]
    )
    gross = next(group for group in state["page"]["warnings"] if group["kind"] == "gross error")
    assert gross["count"] == len(suspects) and gross["where"] == list(suspects["measurement"])


def test_a_bad_survey_gets_tromplab_circuit_s_message_with_its_row_and_column(client, tmp_path):
    bad = SURVEY.read_text().replace("screen_feed,9500.0,19000.0,13.47", "screen_feed,9500.0,19000.0,lots", 1)
    upload(client, "flowsheet.csv", FLOWSHEET.read_bytes())
    assert upload(client, "survey.csv", bad.encode())["kind"]["kind"] == "survey"
    state = run(client)
    (tmp_path / "flowsheet.csv").write_bytes(FLOWSHEET.read_bytes())
    (tmp_path / "survey.csv").write_text(bad)
    code, said = run_cli(tmp_path, ["circuit", "flowsheet.csv", "survey.csv", "-o", "results"])
    assert code == 1 and state == {"state": "failed", "message": said.strip()}
    assert "survey.csv" in said and "row" in said and "retained_pct" in said
    assert client.get("/api/download/results.zip").status_code == 404  # nothing half-written to take home


def test_the_bundled_circuit_example_is_a_pair(client):
    described = client.post("/api/example", params={"name": "circuit_example"}).json()
    assert described["circuit"] == {"flowsheet": "circuit_example_flowsheet.csv", "survey": "circuit_example_survey.csv"}
    session = next(iter(client.app.state.sessions._sessions.values()))
    assert sorted(path.name for path in (session.folder / "upload").rglob("*.csv")) == [
        "circuit_example_flowsheet.csv", "circuit_example_survey.csv"
    ]  # fmt: skip


# -- trend ------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_trend_surveys_are_charted_and_downloaded_as_tromplab_trend_writes_them(client, tmp_path):
    assert upload(client, TREND.name, TREND.read_bytes())["kind"]["commands"] == ["tromplab fit", "tromplab trend"]
    state = run(client, {"size_unit": "um", "baseline": "6"}, command="tromplab trend")
    assert state["state"] == "done", state
    assert state["downloads"] == ["results.zip", "trend_report.html"]
    shutil.copyfile(TREND, tmp_path / TREND.name)
    assert run_cli(tmp_path, ["trend", TREND.name, "-o", "results", "--size-unit=um", "--baseline=6"])[0] == 0
    assert_folder_is_the_command_s(client, tmp_path)
    assert_same_file(client.get("/api/download/trend_report.html").content, tmp_path / "results" / "trend_report.html")
    page = state["page"]
    flags = pd.read_csv(tmp_path / "results" / "trend_surveys.csv")
    assert page["surveys"] == list(flags["survey"]) and page["dates"] == list(flags["date"])
    assert page["baseline"] == list(flags["baseline"]) and sum(page["baseline"]) == 6
    assert page["change_points"] == list(flags.loc[flags["change_point"], "survey"])
    charted = pd.read_csv(tmp_path / "results" / "trend.csv")
    assert [chart["quantity"] for chart in page["charts"]] == list(dict.fromkeys(charted["quantity"]))
    for chart in page["charts"]:
        rows = charted[charted["quantity"] == chart["quantity"]]
        for column in ("value", "low", "high", "ewma", "ewma_low", "ewma_high"):
            expected = [None if pd.isna(v) else pytest.approx(v, rel=1e-12) for v in rows[column]]
            assert chart[column] == expected, column
        assert chart["alarm"] == list(rows["ewma_alarm"])
    assert client.get("/api/download/report.html").status_code == 404  # not a file of tromplab trend


def test_a_bad_trend_file_gets_tromplab_trend_s_message_with_its_row_and_column(client, tmp_path):
    bad = TREND.read_text().replace("2025-01-13", "13th of January", 1)
    assert upload(client, "bad trend.csv", bad.encode())["kind"]["kind"] == "trend"
    state = run(client, command="tromplab trend")
    (tmp_path / "bad trend.csv").write_text(bad)
    code, said = run_cli(tmp_path, ["trend", "bad trend.csv", "-o", "results"])
    assert code == 1 and state == {"state": "failed", "message": said.strip()}
    assert "bad trend.csv" in said and "row" in said and "date" in said


# -- one fit for the folder and the report ----------------------------------------------------------
def _page_run(tmp_path: Path, source: Path, options: list[str]) -> jobs.PageRun:
    folder = tmp_path / "page"
    folder.mkdir()
    shutil.copyfile(source, folder / source.name)
    return jobs.PageRun(folder, (source.name,), tuple(options), tuple(options))


@pytest.mark.slow
@pytest.mark.parametrize(
    ("source", "fit_options", "report_options"),
    [
        (DATASETS / "double_deck_screen_decks_lab.csv", ["--size-unit=mm", "--ci=0.9", "--rank-by=aicc"],
         ["--size-unit=mm", "--ci=0.9", "--rank-by=aicc"]),
        # 24 experiments (the report's condensed form), a bootstrap, which tromplab report does not take
        (TREND, ["--ci=0.8", "--bootstrap=20", "--seed=3", "--alpha=0.1"], ["--ci=0.8", "--alpha=0.1"]),
    ],
)  # fmt: skip
def test_the_page_fits_once_and_its_report_is_tromplab_report_s(tmp_path, monkeypatch, source, fit_options, report_options):
    import tromplab.workbench

    fitted = []
    fit_to_folder = tromplab.workbench.fit_to_folder
    monkeypatch.setattr(tromplab.workbench, "fit_to_folder", lambda *a, **k: fitted.append(1) or fit_to_folder(*a, **k))
    monkeypatch.setattr(tromplab.workbench, "fit_with_settings", lambda *a, **k: pytest.fail("fitted a second time"))
    monkeypatch.chdir(tmp_path)  # the run moves into its folder
    folder = tmp_path / "page"
    folder.mkdir()
    shutil.copyfile(source, folder / source.name)
    page_run = jobs.PageRun(folder, (source.name,), tuple(fit_options), tuple(report_options))
    jobs.run_command(page_run)
    assert not (folder / jobs.ERROR_FILE).exists(), (folder / jobs.ERROR_FILE).read_text()
    assert fitted == [1] and (folder / jobs.PAGE_FILE).is_file()
    monkeypatch.undo()
    cli = tmp_path / "cli"
    cli.mkdir()
    shutil.copyfile(source, cli / source.name)
    assert run_cli(cli, ["fit", source.name, "-o", "results", "--excel", *fit_options])[0] == 0
    assert run_cli(cli, ["report", source.name, "-o", "report.html", *report_options])[0] == 0
    assert_same_file((folder / "report.html").read_bytes(), cli / "report.html")
    for path in (cli / "results").rglob("*"):
        if path.is_file():
            assert_same_file((folder / "results" / path.relative_to(cli / "results")).read_bytes(), path)


def test_an_option_of_fit_that_changes_the_fits_makes_the_report_fit_again():
    import tromplab
    from tromplab.app.payload import report_bench
    from tromplab.validation import FitSettings

    points = tromplab.read_experiments(DATASETS / "double_deck_screen_decks_lab.csv", size_unit="mm")
    bench = tromplab.fit_experiments(points, ci=0.9)
    assert report_bench(bench, FitSettings(size_unit=bench.settings.size_unit)) is not None
    assert report_bench(bench, FitSettings(size_unit=bench.settings.size_unit, single_fits=True)) is None
    assert report_bench(bench, FitSettings(size_unit=bench.settings.size_unit, alpha=0.1)) is None
