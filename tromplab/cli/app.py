"""``tromplab app``: start the local web workbench (:mod:`tromplab.app`) and open it in the browser."""

from __future__ import annotations

import importlib
import importlib.util
import sys

from ..errors import OptionError
from ..validation import check_count, cli_type

DEFAULT_PORT = 8765
#: Largest upload the page accepts by default, MiB.
DEFAULT_MAX_UPLOAD_MB = 20


def add_app(commands) -> None:
    app = commands.add_parser(
        "app",
        help="local web workbench: drop a lab sheet on a page, fit, rank, look at the curves, download the results",
        description="Start a local web server with the tromplab page and open it in the default browser. It listens "
        "on the loopback interface (127.0.0.1) only, unless --host names another address and --allow-remote says so. "
        "Each browser session works in a temporary folder, removed when the page is closed or the server stops. "
        "Needs the app extra: pip install 'tromplab[app]'.",
    )
    app.add_argument(
        "--port",
        type=cli_type(check_count, "--port", minimum=1, maximum=65535),
        default=DEFAULT_PORT,
        help="port (default %(default)s)",
    )
    app.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1, this computer only)")
    app.add_argument(
        "--allow-remote",
        action="store_true",
        help="allow a --host other than the loopback interface: anyone who can reach it can use the page and "
        "read what is uploaded in their own session (there is no login)",
    )
    app.add_argument("--no-browser", action="store_true", help="do not open the page in the browser")
    app.add_argument(
        "--max-upload-mb",
        type=cli_type(check_count, "--max-upload-mb", minimum=1, maximum=10_000),
        default=DEFAULT_MAX_UPLOAD_MB,
        help="largest file the page accepts, MiB (default %(default)s)",
    )
    app.set_defaults(run=_run_app, imports=())


def _run_app(args) -> int:
    from .startup import require

    for module in ("starlette", "uvicorn", "plotly"):
        require(module, "tromplab app", "pip install 'tromplab[app]'")
    # the server sits above the command line (it reads the commands' parsers to build its forms):
    # it is named here, not imported, as the console script names the command line
    server = importlib.import_module("tromplab.app.server")
    if not server.is_loopback(args.host):
        if not args.allow_remote:
            raise OptionError(
                "--host", f"{args.host} is not this computer's loopback interface; add --allow-remote to listen there"
            )
        print(f"tromplab app: warning: listening on {args.host}: anyone who can reach this address can use the page "
              "(there is no login); stop it with Ctrl+C", file=sys.stderr)  # fmt: skip
    server.serve(host=args.host, port=args.port, open_browser=not args.no_browser, max_upload=args.max_upload_mb * 2**20)
    return 0
