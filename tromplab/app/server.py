"""The local server of ``tromplab app``: a Starlette application serving one static page and
a small JSON interface over the library, run by uvicorn.

Safety of a local server: it listens on the loopback interface unless told otherwise; it
answers only requests addressed to a loopback name (no DNS rebinding); the session cookie is
HttpOnly and SameSite=Strict, and every request that changes something must carry the page's
own header (no cross-site request can); uploads have a size limit; the page is served with a
Content-Security-Policy that allows scripts from the server alone, and the page puts every
text that comes from a file into the document as text, never as HTML.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import ipaddress
import shutil
import zipfile
from importlib import resources
from pathlib import Path

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.middleware import Middleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Route

from .forms import OptionsRefused, arguments_from_form, command_parser, form_options, parse_arguments
from .jobs import COMMANDS as RUN_COMMANDS
from .jobs import RESULTS_FOLDER, Job, PageRun
from .kinds import ACCEPTED_SUFFIXES, CIRCUIT_DESIGN, CIRCUIT_ROLES, command_name, sheet_names, table_kind
from .sessions import Session, Sessions, Upload, safe_file_name

COOKIE = "tromplab_session"
#: Largest upload, bytes (``tromplab app --max-upload-mb``): a lab table is kilobytes, a batch
#: of thousands of experiments a few megabytes.
DEFAULT_MAX_UPLOAD = 20 * 1024 * 1024
#: The header every request that changes something carries (set by the page's script; a form
#: or request of another site cannot set it without the server's consent, which it never gives).
PAGE_HEADER = "x-tromplab-page"
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "::1", "[::1]")
SECURITY_HEADERS = {
    "content-security-policy": "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
    "img-src 'self' data: blob:; connect-src 'self'; object-src 'none'; base-uri 'none'; frame-ancestors 'none'",
    "x-content-type-options": "nosniff",
    "referrer-policy": "no-referrer",
    "cache-control": "no-store",
}
STATIC_FILES = {"index.html": "text/html", "app.js": "text/javascript", "app.css": "text/css"}
EXAMPLES = {"double_deck_screen_decks_lab.csv": "lab table: the two decks of a double-deck screen (sizes in mm)",
            "classifier_trend_surveys.csv": "Tromp points: 24 weekly surveys of one classifier (sizes in um; fit or trend)",
            "density_tracers_dmc_by_size_synthetic.csv": "density tracers: a dense-medium cyclone, four size fractions",
            "circuit_example": "circuit: flowsheet and survey of a two-deck screen feeding a closed mill and "
                               "hydrocyclone circuit (synthetic)"}  # fmt: skip
#: The files of each example, dropped in this order (an example of two files is a circuit: flowsheet, then survey).
EXAMPLE_FILES = {"circuit_example": ("circuit_example_flowsheet.csv", "circuit_example_survey.csv")}
MEDIA_TYPES = {".zip": "application/zip", ".html": "text/html",
               ".xlsx": "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet"}  # fmt: skip


def is_loopback(host: str) -> bool:
    """Whether ``host`` names the loopback interface only."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def create_app(*, max_upload: int = DEFAULT_MAX_UPLOAD, allowed_hosts=LOOPBACK_NAMES, sessions: Sessions | None = None):
    """The Starlette application of ``tromplab app``.

    Parameters
    ----------
    max_upload : int
        Largest accepted upload in bytes.
    allowed_hosts : sequence of str
        Host names the server answers to (``["*"]`` for any, when it listens beyond loopback).
    sessions : Sessions, optional
        Where the sessions live (a new temporary root by default); closed when the application stops.
    """
    sessions = Sessions() if sessions is None else sessions
    api = _Api(sessions, max_upload)

    @contextlib.asynccontextmanager
    async def lifespan(app):
        sweeper = asyncio.create_task(_sweep_idle(sessions))
        try:
            yield
        finally:
            sweeper.cancel()
            sessions.close()

    routes = [
        Route("/", api.page),
        Route("/static/{name}", api.static),
        Route("/api/session", api.session, methods=["GET"]),
        Route("/api/upload", api.upload, methods=["POST"]),
        Route("/api/example", api.example, methods=["POST"]),
        Route("/api/sheet", api.sheet, methods=["POST"]),
        Route("/api/run", api.run, methods=["POST"]),
        Route("/api/job", api.job, methods=["GET"]),
        Route("/api/cancel", api.cancel, methods=["POST"]),
        Route("/api/download/{name}", api.download, methods=["GET"]),
        Route("/api/end", api.end, methods=["POST"]),
    ]
    app = Starlette(
        routes=routes, lifespan=lifespan, middleware=[Middleware(TrustedHostMiddleware, allowed_hosts=list(allowed_hosts))]
    )
    app.state.sessions = sessions
    return app


async def _sweep_idle(sessions: Sessions) -> None:
    while True:
        await asyncio.sleep(60)
        await run_in_threadpool(sessions.sweep)


def _json(data, status: int = 200, **kwargs) -> JSONResponse:
    return JSONResponse(data, status_code=status, headers=SECURITY_HEADERS, **kwargs)


def _refused(message: str, status: int = 400) -> JSONResponse:
    return _json({"error": message}, status)


class _Api:
    """The page and its JSON interface, over the sessions."""

    def __init__(self, sessions: Sessions, max_upload: int):
        self.sessions = sessions
        self.max_upload = max_upload
        #: the commands the page runs, with their parsers and forms (``report`` follows ``fit``)
        self.parsers = {command: command_parser(*command) for command in RUN_COMMANDS}
        self.forms = {command: form_options(parser) for command, parser in self.parsers.items()}
        self.fit_parser = self.parsers[("fit",)]
        self.report_parser = command_parser("report")
        self.report_options = form_options(self.report_parser)

    # -- the page -------------------------------------------------------------------------
    async def page(self, request: Request) -> Response:
        return _static_response("index.html")

    async def static(self, request: Request) -> Response:
        name = request.path_params["name"]
        if name == "plotly.min.js":  # plotly's own bundle, shipped with its Python package: nothing remote
            path = resources.files("plotly") / "package_data" / "plotly.min.js"
            return FileResponse(str(path), media_type="text/javascript", headers=SECURITY_HEADERS)
        if name not in STATIC_FILES:
            return Response("not found", status_code=404)
        return _static_response(name)

    # -- sessions ---------------------------------------------------------------------------
    async def session(self, request: Request) -> Response:
        session = self.sessions.get(request.cookies.get(COOKIE))
        fresh = session is None
        if fresh:
            session = self.sessions.new()
        response = _json({"examples": EXAMPLES, "max_upload": self.max_upload, "accepted": list(ACCEPTED_SUFFIXES),
                          "upload": _upload_view(session.upload, session) if session.upload else None})  # fmt: skip
        if fresh:
            response.set_cookie(COOKIE, session.token, httponly=True, samesite="strict", path="/")
        return response

    def _session_of(self, request: Request, *, changes: bool = True) -> Session | Response:
        if changes and request.headers.get(PAGE_HEADER) != "1":
            return _refused("this request must come from the tromplab page", 403)
        session = self.sessions.get(request.cookies.get(COOKIE))
        if session is None:
            return _refused("no session: reload the page", 401)
        return session

    async def end(self, request: Request) -> Response:
        # sent by the page as it closes (navigator.sendBeacon cannot set headers); the
        # SameSite=Strict cookie is all it needs: another site's request does not carry it
        self.sessions.end(request.cookies.get(COOKIE))
        response = _json({"ended": True})
        response.delete_cookie(COOKIE, path="/")
        return response

    # -- the table --------------------------------------------------------------------------
    async def upload(self, request: Request) -> Response:
        session = self._session_of(request)
        if isinstance(session, Response):
            return session
        name = request.query_params.get("name", "")
        stored = safe_file_name(name)
        if Path(stored).suffix.lower() not in ACCEPTED_SUFFIXES:
            return _refused(f"the page reads CSV or Excel files ({', '.join(ACCEPTED_SUFFIXES)}); this file is not one")
        too_large = _refused(f"the file is larger than the upload limit of {self.max_upload / 2**20:g} MiB "
                             "(tromplab app --max-upload-mb; or run tromplab fit on it)", 413)  # fmt: skip
        declared = request.headers.get("content-length", "")
        if declared.isdigit() and int(declared) > self.max_upload:  # refused before a byte is read
            return too_large
        body = bytearray()
        async for chunk in request.stream():  # and counted as it comes: the header may be absent or wrong
            body += chunk
            if len(body) > self.max_upload:
                return too_large
        return await self._new_table(session, stored, name, bytes(body))

    async def example(self, request: Request) -> Response:
        session = self._session_of(request)
        if isinstance(session, Response):
            return session
        name = request.query_params.get("name", "")
        if name not in EXAMPLES:
            return _refused("no such example")
        for file in EXAMPLE_FILES.get(name, (name,)):
            data = (resources.files("tromplab.app") / "examples" / file).read_bytes()
            described = await self._new_table(session, file, file, data)
        return described

    async def _new_table(self, session: Session, stored: str, shown: str, data: bytes) -> Response:
        if session.job is not None:
            await run_in_threadpool(session.job.cancel)
            session.job = None
        path = session.upload_folder() / stored
        path.write_bytes(data)
        try:
            sheets = await run_in_threadpool(sheet_names, path)
        except Exception:  # not a workbook after all: the command's reader will say why
            sheets = []
        session.upload = Upload(path, shown, sheets)
        return await self._described(session, sheets[0] if sheets else None)

    async def sheet(self, request: Request) -> Response:
        session = self._session_of(request)
        if isinstance(session, Response):
            return session
        if session.upload is None:
            return _refused("no file yet: drop one on the page or pick an example")
        wanted = (await request.json()).get("sheet")
        if wanted not in session.upload.sheets:
            return _refused("no such sheet in the workbook")
        return await self._described(session, wanted)

    async def _described(self, session: Session, sheet: str | None) -> Response:
        from ..cli.startup import cli_message
        from ..errors import InputError

        upload = session.upload
        try:
            kind = await run_in_threadpool(table_kind, upload.path, sheet)
        except InputError as error:
            session.forget_unused_uploads()
            message = f"tromplab fit: error: {cli_message(error, self.fit_parser)}"
            return _json({**_upload_view(upload, session), "kind": None, "error": message})
        upload.kind = kind.kind
        upload.commands = tuple(command for command in kind.commands if command in self.parsers) or (("fit",),)
        if kind.kind in CIRCUIT_ROLES:
            session.circuit[kind.kind] = upload
        else:  # a table of another kind ends the pairing of a flowsheet with a survey
            session.circuit.clear()
        session.forget_unused_uploads()
        view = _upload_view(upload, session)
        if kind.kind in CIRCUIT_ROLES and sheet is not None and sheet != upload.sheets[0]:
            return _json({**view, "kind": None, "error": "tromplab circuit reads the first sheet of a workbook: "
                          "put the table there, or save the sheet as CSV"})  # fmt: skip
        forms = {command_name(command): [o.as_dict() for o in self.forms[command]] for command in upload.commands}
        return _json({**view, "sheet": sheet, "kind": kind.as_dict(), "forms": forms,
                      "options": forms[command_name(upload.commands[0])]})  # fmt: skip

    # -- runs -------------------------------------------------------------------------------
    async def run(self, request: Request) -> Response:
        session = self._session_of(request)
        if isinstance(session, Response):
            return session
        if session.upload is None:
            return _refused("no file yet: drop one on the page or pick an example")
        wanted = await request.json()
        values, sheet = dict(wanted.get("options") or {}), wanted.get("sheet")
        if sheet is not None and sheet not in session.upload.sheets:
            return _refused("no such sheet in the workbook")
        commands = {command_name(command): command for command in session.upload.commands}
        command = commands.get(wanted.get("command") or command_name(session.upload.commands[0]))
        if command is None:
            return _refused(f"this file is read by {' or '.join(commands)}")
        sources = self._inputs(session, command)
        if isinstance(sources, Response):
            return sources
        inputs = tuple(source.name for source in sources)
        try:
            arguments, report_arguments = self._arguments(command, inputs, values, sheet)
        except OptionsRefused as refusal:
            return _refused(str(refusal))
        if session.job is not None:
            await run_in_threadpool(session.job.cancel)
        folder = session.job_folder()
        for source in sources:
            shutil.copyfile(source, folder / source.name)
        run = PageRun(folder, inputs, tuple(arguments), tuple(report_arguments), command)
        session.job = Job(run)
        await run_in_threadpool(session.job.start)
        report = run.report_command()
        return _json({"command": ["tromplab", *run.command_line()], "report_command": report and ["tromplab", *report]})

    def _inputs(self, session: Session, command: tuple[str, ...]) -> list[Path] | Response:
        """The files the command reads: the flowsheet and the survey of ``circuit``, the flowsheet
        (and the survey when one was dropped) of ``circuit design``, else the table."""
        if command not in (("circuit",), CIRCUIT_DESIGN):
            return [session.upload.path]
        if command == CIRCUIT_DESIGN and "flowsheet" not in session.circuit:
            return _refused("tromplab circuit design reads a flowsheet (and the survey taken, if any): drop the flowsheet too")
        roles = [role for role in CIRCUIT_ROLES if command == ("circuit",) or role in session.circuit]
        missing = [role for role in roles if role not in session.circuit]
        if missing:
            return _refused(f"tromplab circuit reads a flowsheet and a survey: drop the {' and the '.join(missing)} too")
        paths = [session.circuit[role].path for role in roles]
        if len(paths) == 2 and paths[0].name == paths[1].name:
            return _refused(f"the flowsheet and the survey are both named {paths[0].name}: rename one of them")
        return paths

    def _arguments(self, command, inputs, values: dict, sheet) -> tuple[list[str], list[str]]:
        """The arguments of the command (and of ``tromplab report`` after ``fit``) the form's
        ``values`` stand for, checked by the commands' parsers (:class:`OptionsRefused` if not)."""
        arguments = arguments_from_form(self.forms[command], values)
        report_arguments = self._report_arguments(values) if command == ("fit",) else []
        if sheet is not None and command not in (("circuit",), CIRCUIT_DESIGN):
            arguments = [*arguments, f"--sheet={sheet}"]
            report_arguments = [*report_arguments, f"--sheet={sheet}"] if command == ("fit",) else []
        parse_arguments(self.parsers[command], [*inputs, *arguments])
        if command == ("fit",):
            parse_arguments(self.report_parser, [*inputs, *report_arguments])
        return arguments, report_arguments

    def _report_arguments(self, values: dict) -> list[str]:
        """The report's options from the fit's: those ``tromplab report`` has, its ``--ci`` the fit's level if given."""
        known = {option.dest for option in self.report_options}
        shared = {dest: value for dest, value in values.items() if dest in known and dest != "ci"}
        if values.get("ci") not in (None, ""):
            shared["ci"] = values["ci"]
        return arguments_from_form(self.report_options, shared)

    async def job(self, request: Request) -> Response:
        session = self._session_of(request, changes=False)
        if isinstance(session, Response):
            return session
        if session.job is None:
            return _json({"state": "idle"})
        return _json(await run_in_threadpool(session.job.state))

    async def cancel(self, request: Request) -> Response:
        session = self._session_of(request)
        if isinstance(session, Response):
            return session
        if session.job is not None:
            await run_in_threadpool(session.job.cancel)
        return _json({"state": "cancelled"})

    async def download(self, request: Request) -> Response:
        session = self._session_of(request, changes=False)
        if isinstance(session, Response):
            return session
        name = request.path_params["name"]
        if session.job is None or session.job.state()["state"] != "done":
            return _refused("no finished run to download", 404)
        run = session.job.run
        if name not in run.downloads():
            return Response("not found", status_code=404)
        media_type = MEDIA_TYPES[Path(name).suffix]
        headers = {**SECURITY_HEADERS, "content-disposition": f'attachment; filename="{name}"'}
        if name == "results.zip":
            data = await run_in_threadpool(_zipped, run.download(name))
            return Response(data, media_type=media_type, headers=headers)
        return FileResponse(run.download(name), media_type=media_type, headers=headers)


def _upload_view(upload: Upload, session: Session) -> dict:
    pair = {role: session.circuit[role].shown_name if role in session.circuit else None for role in CIRCUIT_ROLES}
    return {"name": upload.shown_name, "stored_as": upload.path.name, "sheets": upload.sheets, "circuit": pair}


def _static_response(name: str) -> Response:
    text = (resources.files("tromplab.app") / "static" / name).read_bytes()
    return Response(text, media_type=STATIC_FILES[name], headers=SECURITY_HEADERS)


def _zipped(folder: Path) -> bytes:
    """The results folder as a zip archive, its files under ``results/`` in name order."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted(folder.rglob("*")):
            if path.is_file():
                archive.write(path, f"{RESULTS_FOLDER}/{path.relative_to(folder).as_posix()}")
    return buffer.getvalue()


def serve(*, host: str = "127.0.0.1", port: int = 8765, open_browser: bool = True, max_upload: int = DEFAULT_MAX_UPLOAD) -> None:
    """Run the server until interrupted (what ``tromplab app`` does); every session's folder is
    removed when it stops."""
    import threading
    import webbrowser

    import uvicorn

    allowed = LOOPBACK_NAMES if is_loopback(host) else ["*"]
    app = create_app(max_upload=max_upload, allowed_hosts=allowed)
    shown_host = f"[{host}]" if ":" in host else host
    address = f"http://{'127.0.0.1' if host in ('localhost',) else shown_host}:{port}/"
    print(f"tromplab app: serving {address} (Ctrl+C stops it; every session's files are removed then)", flush=True)
    if open_browser:
        threading.Timer(1.0, webbrowser.open, args=(address,)).start()
    try:
        uvicorn.run(app, host=host, port=port, log_level="warning", access_log=False)
    finally:
        app.state.sessions.close()
