"""A run of a command for the page, in a process of its own.

The run does what ``tromplab fit INPUT -o results --excel OPTIONS`` and ``tromplab report
INPUT -o report.html OPTIONS`` do, through the same library calls with the arguments parsed by
the same parsers, in a job folder of the session: the input under its own name beside the
``results`` folder and ``report.html``, so the files are those the commands write in a folder
holding the same file. A process of its own, so that a run can be cancelled at any moment (the
process is ended and its folder removed) and a run that fails, even by a bug, leaves the server
serving. The process tells the server how far it is through small JSON files in the job folder,
each written whole (a temporary file renamed).
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

PROGRESS_FILE, PAGE_FILE, ERROR_FILE = "progress.json", "page.json", "error.json"
RESULTS_FOLDER, REPORT_FILE = "results", "report.html"


#: The commands the page runs: for each, the arguments the server adds (where the files go,
#: the workbook and the report written too) and where its downloads are in the job folder.
COMMANDS = {
    ("fit",): {"adds": ("-o", RESULTS_FOLDER, "--excel"), "report": REPORT_FILE, "workbook": f"{RESULTS_FOLDER}/results.xlsx"},
    ("density", "fit"): {"adds": ("-o", RESULTS_FOLDER, "--excel", "--report"), "report": f"{RESULTS_FOLDER}/report.html",
                         "workbook": f"{RESULTS_FOLDER}/results.xlsx"},
}  # fmt: skip


@dataclass(frozen=True)
class FitRun:
    """What a run needs: the job folder, the input's name in it, the command (``("fit",)`` or
    ``("density", "fit")``) and the arguments typed after the input; ``tromplab fit`` is
    followed by ``tromplab report`` with ``report_arguments``."""

    folder: Path
    input_name: str
    fit_arguments: tuple[str, ...]
    report_arguments: tuple[str, ...] = ()
    command: tuple[str, ...] = ("fit",)

    def fit_command(self) -> list[str]:
        """The command line this run stands for (run in its folder), without ``tromplab``."""
        return [*self.command, self.input_name, *COMMANDS[self.command]["adds"], *self.fit_arguments]

    def report_command(self) -> list[str] | None:
        """The ``tromplab report`` command line of a ``fit`` run (None for another command)."""
        if self.command != ("fit",):
            return None
        return ["report", self.input_name, "-o", REPORT_FILE, *self.report_arguments]

    def download(self, name: str) -> Path:
        """Where the download ``report.html`` or ``results.xlsx`` is."""
        return self.folder / COMMANDS[self.command]["report" if name == "report.html" else "workbook"]


def write_json(path: Path, data) -> None:
    """``data`` written whole to ``path`` (a temporary file renamed), so a reader never sees half."""
    staged = path.with_name(f".{path.name}.part")
    staged.write_text(json.dumps(data, allow_nan=False), encoding="utf-8")
    os.replace(staged, path)


def run_fit(run: FitRun) -> None:
    """The work of the job's process: fit, write the folder and the report, then the page's data.

    A bad input or option ends with the command line's message in ``error.json``; anything
    else, a bug, says so there too.
    """
    from ..cli import build_parser
    from ..cli.startup import cli_message
    from ..errors import InputError

    os.chdir(run.folder)
    parser = build_parser()
    command = " ".join(("tromplab", *run.command))
    try:
        if run.command == ("density", "fit"):
            _density_fit(run, parser)
        else:
            _fit_and_report(run, parser)
    except InputError as error:
        write_json(Path(ERROR_FILE), {"message": f"{command}: error: {cli_message(error, _subparser(parser, *run.command))}"})
    except Exception as error:  # a bug in tromplab: said as the command line says it
        write_json(Path(ERROR_FILE), {"message": f"{command}: internal error (a bug in tromplab, please report it): "
                                                 f"{type(error).__name__}: {error}"})  # fmt: skip


def _subparser(parser, *path):
    import argparse

    for name in path:
        actions = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
        parser = actions[0].choices[name]
    return parser


def _density_fit(run: FitRun, parser) -> None:
    """What ``tromplab density fit FILE -o results --excel --report OPTIONS`` does, then the page's data."""
    from ..density import fit_density
    from ..output.outputs import check_output_folder
    from .payload import density_payload

    args = parser.parse_args(run.fit_command())
    check_output_folder(args.outdir, inputs=[args.file])
    _progress("fitting", 0, 0, str(args.file))
    result = fit_density(args.file, ci=args.ci, curves=args.curves, method=args.method, floats_yield=args.floats_yield,
                         sheet=args.sheet, sep=args.sep, decimal=args.decimal)  # fmt: skip
    _progress("writing", 0, 0, "")
    result.save(args.outdir, excel=args.excel, report=args.report)
    write_json(Path(PAGE_FILE), density_payload(result))


def _fit_and_report(run: FitRun, parser) -> None:
    from ..cli.option_groups import lab_options
    from ..loading.lab import read_experiments
    from ..loading.tables import check_input_file
    from ..output.outputs import check_output_folder
    from ..validation import FitSettings
    from ..workbench import check_formula_selection, fit_to_folder, fit_with_settings
    from .payload import page_payload

    args = parser.parse_args(run.fit_command())
    check_formula_selection(args.formulas, args.extended)  # refused before the input is read, as the command does
    check_input_file(args.input)
    check_output_folder(args.outdir, inputs=[args.input])
    _progress("reading", 0, 0, str(args.input))
    experiments = read_experiments(args.input, lab_options(args))
    bench, _ = fit_to_folder(experiments, args.outdir, figures=args.figures, format=args.format, excel=args.excel,
                             source=args.input, settings=FitSettings.from_options(args), progress=_reporter("fitting"))  # fmt: skip
    report = parser.parse_args(run.report_command())
    check_formula_selection(report.formulas, report.extended)
    settings = FitSettings.from_options(report, ci=None)  # as tromplab report: --ci is its tables' level
    report_bench = fit_with_settings(read_experiments(report.input, lab_options(report)), settings,
                                     progress=_reporter("fitting for the report"))  # fmt: skip
    report_bench.check_fitted(report.input)
    report_bench.write_report(report.output, level=report.ci, title=report.title, jobs=report.jobs)
    _progress("drawing", 0, 0, "")
    write_json(Path(PAGE_FILE), page_payload(bench, experiments, args))


def _reporter(phase: str):
    def progress(done, total, label):
        _progress(phase, done, total, str(label))

    return progress


def _progress(phase: str, done: int, total: int, label: str) -> None:
    write_json(Path(PROGRESS_FILE), {"phase": phase, "done": int(done), "total": int(total), "label": label})


def _child(run: FitRun) -> None:
    sys.stdout = sys.stderr = open(os.devnull, "w")  # noqa: SIM115  (the console is the server's)
    run_fit(run)


@dataclass
class Job:
    """A run started for a session: its process and folder; :meth:`state` tells how it stands."""

    run: FitRun
    process: multiprocessing.process.BaseProcess | None = None
    cancelled: bool = field(default=False)

    def start(self) -> None:
        context = multiprocessing.get_context("spawn")  # a fresh interpreter: nothing of the server's threads
        self.process = context.Process(target=_child, args=(self.run,), daemon=True)
        self.process.start()

    def state(self) -> dict:
        """``{"state": "running" | "done" | "failed" | "cancelled", ...}`` with the progress, the
        page's data or the error message."""
        folder = self.run.folder
        if self.cancelled:
            return {"state": "cancelled"}
        if (folder / ERROR_FILE).is_file():
            return {"state": "failed", **_read(folder / ERROR_FILE)}
        if (folder / PAGE_FILE).is_file():
            return {"state": "done", "page": _read(folder / PAGE_FILE)}
        if self.process is not None and not self.process.is_alive():
            return {
                "state": "failed",
                "message": f"tromplab fit: the run stopped unexpectedly (exit code {self.process.exitcode})",
            }
        progress = _read(folder / PROGRESS_FILE) if (folder / PROGRESS_FILE).is_file() else {"phase": "starting"}
        return {"state": "running", "progress": progress}

    def cancel(self) -> None:
        """End the run's process and remove what it wrote."""
        self.cancelled = True
        self.stop()
        shutil.rmtree(self.run.folder, ignore_errors=True)

    def stop(self) -> None:
        if self.process is not None and self.process.is_alive():
            self.process.terminate()
            self.process.join(5)
            if self.process.is_alive():
                self.process.kill()
                self.process.join()


def _read(path: Path) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))
