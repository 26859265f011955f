"""A run of a command for the page, in a process of its own.

A run does what the command does (``tromplab fit INPUT -o results --excel OPTIONS`` with
``tromplab report INPUT -o report.html OPTIONS``, ``tromplab density fit``, ``tromplab circuit
FLOWSHEET SURVEY -o results``, ``tromplab circuit design FLOWSHEET [SURVEY] -o results``, ``tromplab
trend INPUT -o results``), through the same library
calls with the arguments parsed by the same parsers, in a job folder of the session: the inputs
under their own names beside the ``results`` folder, so the files are those the commands write
in a folder holding the same files. A process of its own, so that a run can be cancelled at any
moment (the process is ended and its folder removed) and a run that fails, even by a bug, leaves
the server serving. The process tells the server how far it is through small JSON files in the
job folder, each written whole (a temporary file renamed).
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import signal
import sys
from dataclasses import dataclass, field
from pathlib import Path

from .kinds import command_name

PROGRESS_FILE, PAGE_FILE, ERROR_FILE = "progress.json", "page.json", "error.json"
RESULTS_FOLDER, REPORT_FILE = "results", "report.html"


@dataclass(frozen=True)
class PageCommand:
    """A command the page runs: the arguments the server adds after the inputs (where the files
    go, the workbook and report written too) and its downloads, name -> path in the job folder
    (``results.zip`` is the results folder, zipped)."""

    adds: tuple[str, ...]
    downloads: dict[str, str]


COMMANDS = {
    ("fit",): PageCommand(("-o", RESULTS_FOLDER, "--excel"),
                          {"results.zip": RESULTS_FOLDER, "report.html": REPORT_FILE, "results.xlsx": f"{RESULTS_FOLDER}/results.xlsx"}),
    ("density", "fit"): PageCommand(("-o", RESULTS_FOLDER, "--excel", "--report"),
                                    {"results.zip": RESULTS_FOLDER, "report.html": f"{RESULTS_FOLDER}/report.html",
                                     "results.xlsx": f"{RESULTS_FOLDER}/results.xlsx"}),
    ("circuit",): PageCommand(("-o", RESULTS_FOLDER), {"results.zip": RESULTS_FOLDER}),
    ("circuit", "design"): PageCommand(("-o", RESULTS_FOLDER), {"results.zip": RESULTS_FOLDER}),
    ("trend",): PageCommand(("-o", RESULTS_FOLDER),
                            {"results.zip": RESULTS_FOLDER, "trend_report.html": f"{RESULTS_FOLDER}/trend_report.html"}),
}  # fmt: skip


@dataclass(frozen=True)
class PageRun:
    """What a run needs: the job folder, the inputs' names in it (the flowsheet and the survey
    of ``circuit``, else one table), the command (``("fit",)``, ``("density", "fit")``,
    ``("circuit",)``, ``("trend",)``) and the arguments typed after the inputs; ``tromplab fit``
    is followed by ``tromplab report`` with ``report_arguments``."""

    folder: Path
    inputs: tuple[str, ...]
    arguments: tuple[str, ...]
    report_arguments: tuple[str, ...] = ()
    command: tuple[str, ...] = ("fit",)

    def command_line(self) -> list[str]:
        """The command line this run stands for (run in its folder), without ``tromplab``."""
        return [*self.command, *self.inputs, *COMMANDS[self.command].adds, *self.arguments]

    def report_command(self) -> list[str] | None:
        """The ``tromplab report`` command line of a ``fit`` run (None for another command)."""
        if self.command != ("fit",):
            return None
        return ["report", *self.inputs, "-o", REPORT_FILE, *self.report_arguments]

    def downloads(self) -> dict[str, str]:
        """Name -> path in the job folder of each download of this run."""
        return COMMANDS[self.command].downloads

    def download(self, name: str) -> Path:
        """Where the download ``name`` is (``results.zip``: the results folder)."""
        return self.folder / self.downloads()[name]


def write_json(path: Path, data) -> None:
    """``data`` written whole to ``path`` (a temporary file renamed), so a reader never sees half."""
    staged = path.with_name(f".{path.name}.part")
    staged.write_text(json.dumps(data, allow_nan=False), encoding="utf-8")
    os.replace(staged, path)


def run_command(run: PageRun) -> None:
    """The work of the job's process: run the command, write its folder, then the page's data.

    A bad input or option ends with the command line's message in ``error.json``; a result out
    of range as the command line says it (``failed:``); anything else, a bug, says so there too.
    """
    from ..cli import build_parser
    from ..cli.startup import cli_message, cli_words, words_of
    from ..errors import InputError, ResultError

    os.chdir(run.folder)
    parser = build_parser()
    command = command_name(run.command)
    own = subparser(parser, *run.command)
    try:
        with words_of(parser):
            RUNNERS[run.command](run, parser)
    except InputError as error:
        write_json(Path(ERROR_FILE), {"message": f"{command}: error: {cli_message(error, own)}"})
    except ResultError as error:
        write_json(Path(ERROR_FILE), {"message": f"{command}: failed: {cli_words(str(error), own)}"})
    except Exception as error:  # a bug in tromplab: said as the command line says it
        write_json(Path(ERROR_FILE), {"message": f"{command}: internal error (a bug in tromplab, please report it): "
                                                 f"{type(error).__name__}: {error}"})  # fmt: skip


def subparser(parser, *path):
    """The parser of the sub-command ``path`` under the whole command line's ``parser``."""
    import argparse

    for name in path:
        actions = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
        parser = actions[0].choices[name]
    return parser


def _density_fit(run: PageRun, parser) -> None:
    """What ``tromplab density fit FILE -o results --excel --report OPTIONS`` does, then the page's data."""
    from ..density import fit_density
    from ..output.outputs import check_output_folder
    from .payload import density_payload

    args = parser.parse_args(run.command_line())
    check_output_folder(args.outdir, inputs=[args.file])
    _progress("fitting", 0, 0, str(args.file))
    result = fit_density(args.file, ci=args.ci, curves=args.curves, method=args.method, floats_yield=args.floats_yield,
                         sheet=args.sheet, sep=args.sep, decimal=args.decimal)  # fmt: skip
    _progress("writing", 0, 0, "")
    result.save(args.outdir, excel=args.excel, report=args.report)
    write_json(Path(PAGE_FILE), density_payload(result))


def _fit_and_report(run: PageRun, parser) -> None:
    """What ``tromplab fit`` and then ``tromplab report`` do, from one fit (:func:`report_bench`)."""
    from ..cli.option_groups import lab_options
    from ..loading.lab import read_experiments
    from ..loading.tables import check_input_file
    from ..output.outputs import check_output_folder
    from ..validation import FitSettings
    from ..workbench import check_formula_selection, fit_to_folder, fit_with_settings
    from .payload import page_payload, report_bench

    args = parser.parse_args(run.command_line())
    check_formula_selection(args.formulas, args.extended)  # refused before the input is read, as the command does
    check_input_file(args.input)
    check_output_folder(args.outdir, inputs=[args.input])
    _progress("reading", 0, 0, str(args.input))
    experiments = read_experiments(args.input, lab_options(args))
    bench, _ = fit_to_folder(experiments, args.outdir, figures=args.figures, format=args.format, excel=args.excel,
                             source=args.input, settings=FitSettings.from_options(args), progress=_reporter("fitting"))  # fmt: skip
    report = parser.parse_args(run.report_command())
    settings = FitSettings.from_options(report, ci=None)  # as tromplab report: --ci is its tables' level
    reported = report_bench(bench, settings)
    if reported is None:  # an option the report does not take changed the fits: it fits as tromplab report does
        reported = fit_with_settings(read_experiments(report.input, lab_options(report)), settings,
                                     progress=_reporter("fitting for the report"))  # fmt: skip
    _progress("writing the report", 0, 0, "")
    reported.check_fitted(report.input)
    reported.write_report(report.output, level=report.ci, title=report.title, jobs=report.jobs)
    _progress("drawing", 0, 0, "")
    write_json(Path(PAGE_FILE), page_payload(bench, experiments, args))


def _circuit(run: PageRun, parser) -> None:
    """What ``tromplab circuit FLOWSHEET SURVEY -o results OPTIONS`` does, then the page's data."""
    from ..circuit import reconcile_circuit
    from ..cli.circuit import error_model_of
    from ..output.outputs import check_output_folder
    from .circuit_page import circuit_payload

    args = parser.parse_args(run.command_line())
    check_output_folder(args.outdir, inputs=[args.flowsheet, args.measurements])
    _progress("reconciling", 0, 0, str(args.measurements))
    result = reconcile_circuit(args.flowsheet, args.measurements, fit=args.fit, errors=error_model_of(args), alpha=args.alpha,
                               size_unit=args.size_unit, exclude=args.exclude, weighting=args.weighting,
                               progress=_reporter("reconciling"))  # fmt: skip
    result.save(args.outdir, figures=not args.no_figures)
    _progress("drawing", 0, 0, "")
    write_json(Path(PAGE_FILE), circuit_payload(result, args.outdir))


def _circuit_design(run: PageRun, parser) -> None:
    """What ``tromplab circuit design FLOWSHEET [SURVEY] -o results OPTIONS`` does, then the page's data."""
    from ..cli.circuit import design_of_options
    from .circuit_page import design_payload

    args = parser.parse_args(run.command_line())
    _progress("designing", 0, 0, str(args.flowsheet))
    advice = design_of_options(args, _reporter("designing"))
    advice.save(args.outdir)
    _progress("drawing", 0, 0, "")
    write_json(Path(PAGE_FILE), design_payload(advice, args.outdir))


def _trend(run: PageRun, parser) -> None:
    """What ``tromplab trend INPUT -o results OPTIONS`` does, then the page's data."""
    from ..cli.option_groups import lab_options
    from ..loading.tables import check_input_file
    from ..output.outputs import check_output_folder
    from ..trend import monitor_surveys, read_surveys, write_trend
    from .trend_page import trend_payload

    args = parser.parse_args(run.command_line())
    check_input_file(args.input)
    check_output_folder(args.outdir, inputs=[args.input])
    _progress("reading", 0, 0, str(args.input))
    surveys = read_surveys(args.input, lab_options(args))
    _progress("fitting and charting", 0, 0, f"{len(surveys)} surveys")
    result = monitor_surveys(surveys, formula=args.formula, baseline=args.baseline, alpha=args.alpha)
    _progress("writing", 0, 0, "")
    write_trend(result, args.outdir, size_unit=args.size_unit, figures=not args.no_figures)
    write_json(Path(PAGE_FILE), trend_payload(result, size_unit=args.size_unit))


RUNNERS = {("fit",): _fit_and_report, ("density", "fit"): _density_fit, ("circuit",): _circuit,
           ("circuit", "design"): _circuit_design, ("trend",): _trend}  # fmt: skip


def _reporter(phase: str):
    def progress(done, total, label):
        _progress(phase, done, total, str(label))

    return progress


def _progress(phase: str, done: int, total: int, label: str) -> None:
    write_json(Path(PROGRESS_FILE), {"phase": phase, "done": int(done), "total": int(total), "label": label})


def _child(run: PageRun) -> None:
    if hasattr(os, "setsid"):  # a process group of its own: cancelling ends its workers with it
        os.setsid()
    sys.stdout = sys.stderr = open(os.devnull, "w")  # noqa: SIM115  (the console is the server's)
    run_command(run)


@dataclass
class Job:
    """A run started for a session: its process and folder; :meth:`state` tells how it stands."""

    run: PageRun
    process: multiprocessing.process.BaseProcess | None = None
    cancelled: bool = field(default=False)

    def start(self) -> None:
        context = multiprocessing.get_context("spawn")  # a fresh interpreter: nothing of the server's threads
        # not a daemon: a run spreads a batch over worker processes as the command does (a daemon
        # process may not start any); its process group is ended with it (stop)
        self.process = context.Process(target=_child, args=(self.run,), daemon=False)
        self.process.start()

    def state(self) -> dict:
        """``{"state": "running" | "done" | "failed" | "cancelled", ...}`` with the progress, the
        page's data (and the downloads) or the error message."""
        folder = self.run.folder
        if self.cancelled:
            return {"state": "cancelled"}
        if (folder / ERROR_FILE).is_file():
            return {"state": "failed", **_read(folder / ERROR_FILE)}
        if (folder / PAGE_FILE).is_file():
            return {"state": "done", "page": _read(folder / PAGE_FILE), "downloads": list(self.run.downloads())}
        if self.process is not None and not self.process.is_alive():
            return {
                "state": "failed",
                "message": f"{command_name(self.run.command)}: the run stopped unexpectedly (exit code {self.process.exitcode})",
            }
        progress = _read(folder / PROGRESS_FILE) if (folder / PROGRESS_FILE).is_file() else {"phase": "starting"}
        return {"state": "running", "progress": progress}

    def cancel(self) -> None:
        """End the run's process and remove what it wrote."""
        self.cancelled = True
        self.stop()
        shutil.rmtree(self.run.folder, ignore_errors=True)

    def stop(self) -> None:
        """End the run's process and the workers it started (its process group)."""
        if self.process is None or not self.process.is_alive():
            return
        _signal_run(self.process, signal.SIGTERM)  # the group, workers too, while its leader is not reaped
        self.process.join(5)
        if self.process.is_alive():
            _signal_run(self.process, getattr(signal, "SIGKILL", signal.SIGTERM))
            self.process.join()


def _signal_run(process, number: int) -> None:
    """Send ``number`` to the run's process group (its own, made by :func:`_child`), or to the
    process alone where there are no groups or the group is not made yet."""
    try:
        if hasattr(os, "killpg") and os.getpgid(process.pid) == process.pid:
            os.killpg(process.pid, number)
        else:
            os.kill(process.pid, number)
    except ProcessLookupError:
        pass  # ended already


def _read(path: Path) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))
