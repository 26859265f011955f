"""``tromplab app`` through Starlette's test client: the form is the command line's, the
downloads are the command's files byte for byte, a bad file or option gets the command line's
message, and the server is safe: sessions apart, uploads capped, requests from elsewhere refused,
a failing or cancelled run leaving it serving. The page in a real browser: test_app_browser.py."""

from __future__ import annotations

import multiprocessing
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

pytest.importorskip("starlette", reason="the app extra is not installed: pip install -e '.[test]'")
pytest.importorskip("httpx", reason="Starlette's test client needs httpx: pip install -e '.[test]'")

from starlette.testclient import TestClient  # noqa: E402

from tests.app_support import HOSTILE_NAMES, assert_same_file, points_csv, run_cli, wait_for_run, zip_members  # noqa: E402
from tests.conftest import DATASETS  # noqa: E402
from tests.test_formula_injection import assert_no_formula_cell_in_csv, assert_no_formula_cell_in_workbook  # noqa: E402
from tromplab.app.forms import SERVER_CHOSEN, command_parser, form_options  # noqa: E402
from tromplab.app.jobs import Job  # noqa: E402
from tromplab.app.server import create_app, is_loopback  # noqa: E402
from tromplab.app.sessions import Sessions, safe_file_name  # noqa: E402

PAGE = {"x-tromplab-page": "1"}


@pytest.fixture
def app():
    return create_app()


@pytest.fixture
def client(app):
    with TestClient(app, base_url="http://127.0.0.1", headers=PAGE) as client:
        client.get("/api/session")
        yield client


def upload(client, name: str, data: bytes):
    return client.post("/api/upload", params={"name": name}, content=data)


def run(client, options: dict | None = None, sheet=None) -> dict:
    started = client.post("/api/run", json={"options": options or {}, "sheet": sheet})
    assert started.status_code == 200, started.text
    return wait_for_run(client)


# -- the form is the command line's ---------------------------------------------------------------
def test_the_form_offers_every_option_of_tromplab_fit_but_those_the_server_chooses():
    parser = command_parser("fit")
    declared = {action.dest for action in parser._actions if action.option_strings} - SERVER_CHOSEN
    offered = {option.dest: option for option in form_options(parser)}
    assert set(offered) == declared - {"figures"} | {"figures"}  # --no-figures is --figures none, one field
    for action in parser._actions:
        if action.dest in offered and action.choices:
            assert offered[action.dest].choices == tuple(action.choices)
    assert offered["alpha"].default == "0.05" and "(0, 1)" in offered["alpha"].help  # the help with its range


def test_a_bad_option_gets_the_command_lines_own_message(client, tmp_path):
    assert upload(client, "points.csv", points_csv(("A",)).encode()).status_code == 200
    refused = client.post("/api/run", json={"options": {"alpha": "2"}})
    assert refused.status_code == 400
    shutil.copyfile(DATASETS / "double_deck_screen_decks_lab.csv", tmp_path / "points.csv")
    code, said = run_cli(tmp_path, ["fit", "points.csv", "--alpha=2"])
    assert code == 2 and refused.json()["error"] == said.strip()


@pytest.mark.slow
def test_a_bad_file_gets_the_command_lines_own_message_naming_row_and_column(client, tmp_path):
    bad = points_csv(("A",)).replace("156.0,0.442", "156.0,oops").encode()
    described = upload(client, "bad points.csv", bad).json()
    assert described["kind"]["kind"] == "points"
    state = run(client)
    (tmp_path / "bad points.csv").write_bytes(bad)
    code, said = run_cli(tmp_path, ["fit", "bad points.csv", "-o", "results", "--excel"])
    assert code == 1 and state == {"state": "failed", "message": said.strip()}
    assert "row" in state["message"] and "partition_fine" in state["message"]
    assert client.get("/api/session").status_code == 200  # still serving


def test_a_file_the_reader_refuses_is_refused_with_the_reader_s_words(client):
    described = upload(client, "empty.csv", b"# only a comment\n").json()
    assert described["kind"] is None and described["error"].startswith("tromplab fit: error: ")
    assert "empty.csv" in described["error"]


def test_each_kind_is_told_and_offered_the_options_of_its_command(client):
    flowsheet = (DATASETS / "circuit_example_flowsheet.csv").read_bytes()
    described = upload(client, "flowsheet.csv", flowsheet).json()
    assert described["kind"]["kind"] == "flowsheet" and described["kind"]["command"] == "tromplab circuit"
    assert described["circuit"] == {"flowsheet": "flowsheet.csv", "survey": None}
    survey = (DATASETS / "circuit_example_survey.csv").read_bytes()
    described = upload(client, "survey.csv", survey).json()
    assert described["kind"] == {"kind": "survey", "label": "a plant survey of a circuit", "command": "tromplab circuit",
                                 "runs_here": True, "commands": ["tromplab circuit", "tromplab circuit design"]}  # fmt: skip
    assert described["circuit"] == {"flowsheet": "flowsheet.csv", "survey": "survey.csv"}  # paired
    assert {option["dest"] for option in described["options"]} == _declared(command_parser("circuit"))
    tracers = (DATASETS / "density_tracers_dmc_by_size_synthetic.csv").read_bytes()
    described = upload(client, "tracers.csv", tracers).json()
    assert described["kind"]["command"] == "tromplab density fit" and described["kind"]["runs_here"] is True
    assert {option["dest"] for option in described["options"]} == _declared(command_parser("density", "fit"))
    assert described["circuit"] == {"flowsheet": None, "survey": None}  # another kind ends the pairing
    trend = (DATASETS / "classifier_trend_surveys.csv").read_bytes()
    described = upload(client, "trend.csv", trend).json()
    assert described["kind"]["kind"] == "trend" and described["kind"]["commands"] == ["tromplab fit", "tromplab trend"]
    assert {option["dest"] for option in described["forms"]["tromplab trend"]} == _declared(command_parser("trend"))
    lab = (DATASETS / "double_deck_screen_decks_lab.csv").read_bytes()
    assert upload(client, "lab.csv", lab).json()["kind"]["kind"] == "lab"
    assert client.post("/api/run", json={"options": {}, "command": "tromplab trend"}).json() == {
        "error": "this file is read by tromplab fit"
    }


def _declared(parser) -> set[str]:
    return {action.dest for action in parser._actions if action.option_strings} - SERVER_CHOSEN


# -- the same library: the downloads are the command's files ----------------------------------------
@pytest.mark.slow
def test_the_downloads_are_the_files_the_commands_write(client, tmp_path):
    lab = DATASETS / "double_deck_screen_decks_lab.csv"
    upload(client, lab.name, lab.read_bytes())
    options = {"size_unit": "mm", "ci": "0.9", "rank_by": "aicc"}
    state = run(client, options)
    assert state["state"] == "done", state
    shutil.copyfile(lab, tmp_path / lab.name)
    assert (
        run_cli(tmp_path, ["fit", lab.name, "-o", "results", "--excel", "--size-unit=mm", "--ci=0.9", "--rank-by=aicc"])[0] == 0
    )
    assert run_cli(tmp_path, ["report", lab.name, "-o", "report.html", "--size-unit=mm", "--ci=0.9", "--rank-by=aicc"])[0] == 0
    members = zip_members(client.get("/api/download/results.zip").content)
    written = sorted(p.relative_to(tmp_path).as_posix() for p in (tmp_path / "results").rglob("*") if p.is_file())
    assert sorted(members) == written
    for name, data in members.items():
        assert_same_file(data, tmp_path / name)
    assert_same_file(client.get("/api/download/report.html").content, tmp_path / "report.html")
    assert_same_file(client.get("/api/download/results.xlsx").content, tmp_path / "results" / "results.xlsx")
    # the page's numbers are the library's: the best fit's d50 is the one in fits.csv
    fits = pd.read_csv(tmp_path / "results" / "fits.csv")
    for experiment in state["page"]["experiments"]:
        best = experiment["best"]
        row = fits[(fits["experiment"] == experiment["name"]) & (fits["formula"] == best["formula"])]
        assert best["d50"] == pytest.approx(row["d50"].iloc[0], rel=1e-12)
        assert row["rank"].iloc[0] == fits[fits["experiment"] == experiment["name"]]["rank"].min()


@pytest.mark.slow
def test_circuit_design_of_a_dropped_flowsheet_writes_what_the_command_writes(client, tmp_path):
    flowsheet = (DATASETS / "circuit_example_flowsheet.csv").read_bytes()
    described = upload(client, "flowsheet.csv", flowsheet).json()
    assert described["kind"]["commands"] == ["tromplab circuit", "tromplab circuit design"]
    assert {option["dest"] for option in described["forms"]["tromplab circuit design"]} == _declared(
        command_parser("circuit", "design")
    )
    refused = client.post("/api/run", json={"options": {}, "command": "tromplab circuit"})
    assert refused.status_code == 400 and "drop the survey too" in refused.json()["error"]
    started = client.post("/api/run", json={"options": {"alpha": "0.1"}, "command": "tromplab circuit design"})
    assert started.json()["command"] == ["tromplab", "circuit", "design", "flowsheet.csv", "-o", "results", "--alpha=0.1"]
    state = wait_for_run(client)
    assert state["state"] == "done", state
    (tmp_path / "flowsheet.csv").write_bytes(flowsheet)
    assert run_cli(tmp_path, ["circuit", "design", "flowsheet.csv", "-o", "results", "--alpha=0.1"])[0] == 0
    page = state["page"]
    assert page["view"] == "circuit" and [table["name"] for table in page["tables"]] == [
        "design.csv", "observability.csv", "simulated_survey.csv"
    ]  # fmt: skip
    assert page["summary"] == (tmp_path / "results" / "summary.txt").read_text(encoding="utf-8").splitlines()
    drawn = {stream["name"] for stream in page["flowsheet"]["streams"]}
    assert drawn == set(pd.read_csv(tmp_path / "flowsheet.csv", comment="#")["stream"])
    members = zip_members(client.get("/api/download/results.zip").content)
    for name in ("design.csv", "observability.csv", "simulated_survey.csv", "summary.txt"):
        assert_same_file(members[f"results/{name}"], tmp_path / "results" / name)


@pytest.mark.slow
def test_density_tracers_are_fitted_and_downloaded_as_tromplab_density_fit_writes_them(client, tmp_path):
    tracers = DATASETS / "density_tracers_dmc_by_size_synthetic.csv"
    upload(client, tracers.name, tracers.read_bytes())
    state = run(client, {"ci": "0.9", "curves": "plain"})
    assert state["state"] == "done", state
    shutil.copyfile(tracers, tmp_path / tracers.name)
    arguments = ["density", "fit", tracers.name, "-o", "results", "--excel", "--report", "--ci=0.9", "--curves=plain"]
    assert run_cli(tmp_path, arguments)[0] == 0
    members = zip_members(client.get("/api/download/results.zip").content)
    assert sorted(members) == sorted(p.relative_to(tmp_path).as_posix() for p in (tmp_path / "results").rglob("*") if p.is_file())
    for name, data in members.items():
        assert_same_file(data, tmp_path / name)
    assert_same_file(client.get("/api/download/report.html").content, tmp_path / "results" / "report.html")
    assert_same_file(client.get("/api/download/results.xlsx").content, tmp_path / "results" / "results.xlsx")
    fits = pd.read_csv(tmp_path / "results" / "fits.csv")
    for experiment in state["page"]["experiments"]:
        best = experiment["best"]
        assert best["d50"] in set(fits.loc[(fits["rank"] == 1) & (fits["curve"] == best["formula"]), "rho50"])


@pytest.mark.slow
def test_an_excel_sheet_is_chosen_and_read_as_the_command_reads_it(client, tmp_path):
    table = pd.read_csv(DATASETS / "double_deck_screen_decks_lab.csv", comment="#")
    with pd.ExcelWriter(tmp_path / "lab.xlsx") as writer:
        pd.DataFrame({"note": ["not this one"]}).to_excel(writer, sheet_name="cover", index=False)
        table.to_excel(writer, sheet_name="lab", index=False)
    described = upload(client, "lab.xlsx", (tmp_path / "lab.xlsx").read_bytes()).json()
    assert described["sheets"] == ["cover", "lab"] and described["kind"]["kind"] == "unknown"
    assert client.post("/api/sheet", json={"sheet": "lab"}).json()["kind"]["kind"] == "lab"
    state = run(client, {"size_unit": "mm"}, sheet="lab")
    assert state["state"] == "done", state
    assert [e["name"] for e in state["page"]["experiments"]] == ["deck_20mesh", "deck_65mesh"]
    assert client.post("/api/run", json={"options": {}, "sheet": "nope"}).status_code == 400


# -- a safe local server ----------------------------------------------------------------------------
@pytest.mark.slow
def test_two_sessions_never_see_each_others_data(app):
    with (
        TestClient(app, base_url="http://127.0.0.1", headers=PAGE) as first,
        TestClient(app, base_url="http://127.0.0.1", headers=PAGE) as second,
    ):
        first.get("/api/session"), second.get("/api/session")
        assert first.cookies["tromplab_session"] != second.cookies["tromplab_session"]
        upload(first, "first.csv", points_csv(("only_first",)).encode())
        assert run(first)["state"] == "done"
        assert second.get("/api/job").json() == {"state": "idle"}
        assert second.get("/api/download/results.zip").status_code == 404
        assert second.post("/api/run", json={"options": {}}).status_code == 400  # no file in this session
        upload(second, "second.csv", points_csv(("only_second",)).encode())
        page = run(second)["page"]
        assert [e["name"] for e in page["experiments"]] == ["only_second"]
        assert b"only_first" not in second.get("/api/download/results.zip").content
        folders = [session.folder for session in app.state.sessions._sessions.values()]
        assert len(folders) == 2 and folders[0].parent == folders[1].parent and folders[0] != folders[1]
        assert not any(p.name == "first.csv" for p in folders[1].rglob("*"))


def test_a_session_s_folder_is_removed_when_it_ends_and_every_folder_when_the_server_stops():
    sessions = Sessions()
    app = create_app(sessions=sessions)
    with TestClient(app, base_url="http://127.0.0.1", headers=PAGE) as client:
        client.get("/api/session")
        upload(client, "a.csv", points_csv(("A",)).encode())
        (folder,) = [session.folder for session in sessions._sessions.values()]
        assert [path.name for path in (folder / "upload").rglob("*.csv")] == ["a.csv"]
        upload(client, "b.csv", points_csv(("B",)).encode())  # the table dropped before is no longer kept
        assert [path.name for path in (folder / "upload").rglob("*.csv")] == ["b.csv"]
        client.post("/api/end")
        assert not folder.exists() and len(sessions) == 0
        client.get("/api/session")
        assert len(sessions) == 1
    assert not sessions.root.exists()  # the server stopped: the root and every session in it removed


def test_idle_sessions_are_swept():
    sessions = Sessions(idle_seconds=0.05)
    session = sessions.new()
    time.sleep(0.1)
    assert sessions.sweep() == 1 and not session.folder.exists()
    sessions.close()


def test_uploads_over_the_limit_are_refused():
    app = create_app(max_upload=1000)
    with TestClient(app, base_url="http://127.0.0.1", headers=PAGE) as client:
        client.get("/api/session")
        refused = upload(client, "big.csv", b"x" * 2000)  # declared too large
        assert refused.status_code == 413 and "upload limit" in refused.json()["error"]
        streamed = upload(client, "big.csv", iter([b"x" * 600, b"x" * 600]))  # no length declared: counted
        assert streamed.status_code == 413 and "upload limit" in streamed.json()["error"]
        assert upload(client, "small.csv", points_csv(("A",)).encode()[:900]).status_code == 200


def test_requests_without_the_page_s_header_or_for_another_host_are_refused(app):
    with TestClient(app, base_url="http://127.0.0.1") as bare:
        bare.get("/api/session")
        assert upload(bare, "a.csv", b"size,partition_fine\n").status_code == 403
        assert bare.post("/api/run", json={}).status_code == 403
    with TestClient(app, base_url="http://attacker.example") as rebound:  # DNS rebinding: a foreign name
        assert rebound.get("/").status_code == 400
    with TestClient(app, base_url="http://127.0.0.1") as fresh:
        assert fresh.get("/api/job").status_code == 401  # no session cookie, no data


def test_the_page_allows_scripts_from_the_server_only(client):
    page = client.get("/")
    policy = page.headers["content-security-policy"]
    assert "script-src 'self'" in policy and "unsafe-inline" not in policy.split("script-src")[1].split(";")[0]
    assert "http" not in page.text.replace("http-equiv", "")  # nothing loaded from elsewhere
    assert client.get("/static/plotly.min.js").status_code == 200
    assert client.get("/static/..%2Fserver.py").status_code == 404


def test_uploaded_names_are_stored_under_a_safe_name():
    assert safe_file_name("<script>alert(1)</script>.csv") == "script_.csv"
    assert safe_file_name("../../etc/passwd.csv") == "passwd.csv"
    assert safe_file_name("C:\\lab\\my lab (1).xlsx") == "my lab (1).xlsx"
    assert safe_file_name(".hidden.csv") == "hidden.csv"


@pytest.mark.slow
def test_the_downloads_carry_no_formula_cells(client, tmp_path):
    names = ("=1+1", "@SUM(A1)", "-150+75")
    upload(client, "names.csv", points_csv(names).encode())
    assert run(client)["state"] == "done"
    members = zip_members(client.get("/api/download/results.zip").content)
    for name, data in members.items():
        (tmp_path / Path(name).name).write_bytes(data)
    for csv in tmp_path.glob("*.csv"):
        assert_no_formula_cell_in_csv(csv)
    (tmp_path / "from_app.xlsx").write_bytes(client.get("/api/download/results.xlsx").content)
    assert_no_formula_cell_in_workbook(tmp_path / "from_app.xlsx")


@pytest.mark.slow
def test_names_reach_the_page_as_data_never_as_markup(client):
    upload(client, "hostile.csv", points_csv().encode())
    page = run(client)["page"]
    assert [e["name"] for e in page["experiments"]] == list(HOSTILE_NAMES)  # JSON text; the page sets it as text
    script = client.get("/static/app.js").text
    assert "innerHTML" not in script and "insertAdjacentHTML" not in script and "outerHTML" not in script


@pytest.mark.slow
def test_a_cancelled_run_stops_and_leaves_nothing(client):
    upload(client, "slow.csv", (DATASETS / "classifier_trend_surveys.csv").read_bytes())
    assert client.post("/api/run", json={"options": {"bootstrap": "3000"}}).status_code == 200
    time.sleep(1.0)
    session = next(iter(client.app.state.sessions._sessions.values()))
    job = session.job
    assert client.get("/api/job").json()["state"] == "running"
    assert client.post("/api/cancel").json() == {"state": "cancelled"}
    assert client.get("/api/job").json() == {"state": "cancelled"}
    assert not job.process.is_alive() and not job.run.folder.exists()
    assert _living_in_group(job.process.pid) == []  # the run's worker processes ended with it
    upload(client, "next.csv", points_csv(("A",)).encode())
    assert run(client)["state"] == "done"  # and the next run goes on as usual


def _leader_with_a_worker() -> None:
    """A run's process as :func:`tromplab.app.jobs._child` makes it (a process group of its own)
    with a worker process of its own, as a batch spread over workers has."""
    os.setsid()
    subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    time.sleep(120)


@pytest.mark.skipif(not hasattr(os, "setsid"), reason="process groups are POSIX's")
def test_stopping_a_run_ends_the_worker_processes_it_started():
    process = multiprocessing.get_context("spawn").Process(target=_leader_with_a_worker)
    process.start()
    ends = time.monotonic() + 60
    while len(_living_in_group(process.pid, wait=0)) < 2:  # the leader and its worker
        assert time.monotonic() < ends, "the worker did not start"
        time.sleep(0.2)
    Job(run=None, process=process).stop()
    assert not process.is_alive() and _living_in_group(process.pid) == []


def _living_in_group(group: int, *, wait: float = 5.0) -> list[int]:
    """The processes of process group ``group`` that are neither ended nor zombies, after at most ``wait`` s."""
    psutil = pytest.importorskip("psutil")
    ends = time.monotonic() + wait
    while True:
        living = []
        for process in psutil.process_iter(["status"]):
            try:
                if os.getpgid(process.pid) == group and process.info["status"] != psutil.STATUS_ZOMBIE:
                    living.append(process.pid)
            except (ProcessLookupError, psutil.Error):
                continue
        if not living or time.monotonic() > ends:
            return living
        time.sleep(0.2)


@pytest.mark.slow
def test_a_run_that_breaks_says_so_and_the_server_stays_up(client, monkeypatch):
    upload(client, "a.csv", points_csv(("A",)).encode())
    session = next(iter(client.app.state.sessions._sessions.values()))
    client.post("/api/run", json={"options": {}})
    session.job.process.kill()  # the run's process dies as a crash would end it
    session.job.process.join()
    state = wait_for_run(client)
    assert state["state"] == "failed" and "stopped unexpectedly" in state["message"]
    assert run(client)["state"] == "done"


def test_only_the_loopback_interface_is_taken_without_allow_remote(tmp_path):
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.10") and not is_loopback("example.org")
    code, said = run_cli(tmp_path, ["app", "--host", "0.0.0.0", "--no-browser"])
    assert code == 2 and "--host 0.0.0.0 is not this computer's loopback interface; add --allow-remote" in said
