"""Entry point of the ``tromplab`` command and of ``python -m tromplab``: signal handling first.

A command imports numpy, pandas, scipy and lmfit (up to a second).  An interrupt in that
second used to end in Python's own ``KeyboardInterrupt`` traceback or a silent kill.
``import tromplab`` loads its public names lazily and imports none of them, and this module
imports only :mod:`gc`, :mod:`os`, :mod:`signal` and :mod:`sys`: the console script
(``tromplab._launch:main``) and ``tromplab/__main__.py`` install the handling here, then import
the command line, which imports the command's modules before it starts the command (and calls
back to install the command's own handling).  An interrupt at any moment prints one line and
exits with 130 (SIGINT) or 143 (SIGTERM); during start-up nothing has been written yet, and once
the command has returned (while the interpreter shuts down its pools) the outputs are final.
"""

import gc
import os
import signal
import sys

EXIT_INTERRUPTED = 130  # 128 + SIGINT
EXIT_TERMINATED = 143  # 128 + SIGTERM


def _leave(signum, moment: str) -> None:
    """One line on stderr, then exit 130 (SIGINT) or 143 (SIGTERM) at once."""
    what = "terminated (SIGTERM)" if signum == signal.SIGTERM else "interrupted"
    os.write(2, f"tromplab: {what} {moment}\n".encode())
    os._exit(EXIT_TERMINATED if signum == signal.SIGTERM else EXIT_INTERRUPTED)


def _stop_during_start_up(signum, frame):
    # nothing is staged or written before the command line runs, so leaving at once is safe;
    # os._exit skips the half-finished imports' clean-up, which could itself be interrupted
    _leave(signum, "while starting; nothing was written")


def _stop_while_exiting(signum, frame):
    # the command has returned and its outputs are in place (or it failed and said so); the
    # interpreter is closing process pools and clients, where an exception would only print a
    # traceback of Python's own: leave at once instead, after what was already printed
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # closed or a broken pipe: nothing more can be shown
            pass
    _leave(signum, "while exiting; the command had finished")


def _handle(signum, handler) -> None:
    if signal.getsignal(signum) is not signal.SIG_IGN:  # ignored on purpose (``nohup``, a shell's ``&``): keep it so
        signal.signal(signum, handler)


#: The thread pools of the linear algebra, one thread each unless the caller set them (before
#: numpy is imported: the libraries read them once).  A command's matrices are small (a survey's
#: Jacobian is a few hundred square; a fit's a few dozen) and its parallelism is its worker
#: processes: a pool of BLAS threads per process only spins.  Measured (docs/performance.md):
#: ``tromplab circuit`` on the bundled example with assays took 15.2 s of wall time and 9.3 s of
#: CPU with OpenBLAS's default pool on two loaded cores, 2.6 s and 1.6 s with one thread.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def main() -> int:
    """Run ``tromplab`` with SIGINT and SIGTERM handled from the first line on."""
    _handle(signal.SIGINT, _stop_during_start_up)
    _handle(signal.SIGTERM, _stop_during_start_up)
    for variable in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(variable, "1")
    from . import cli

    def command_handling():
        # from here on the command line's own handling applies: SIGINT raises KeyboardInterrupt and
        # SIGTERM cli.Terminated, so the output folder is cleaned up as the command unwinds; until
        # the command has imported its modules (cli.main) an interrupt still leaves at once
        _handle(signal.SIGTERM, cli.raise_terminated)
        _handle(signal.SIGINT, signal.default_int_handler)

    try:
        return cli.main(on_start=command_handling)
    except KeyboardInterrupt as interruption:  # between the handlers above and cli.main's own
        return cli.interrupted(interruption)
    finally:
        _handle(signal.SIGINT, _stop_while_exiting)
        _handle(signal.SIGTERM, _stop_while_exiting)
        # the process ends here: its objects handed to the collector's permanent generation, so
        # the interpreter's shutdown does not run full collections over the hundreds of
        # thousands of objects of the numerical stack (about 0.4 s of CPU after a fit of 1,024
        # experiments); the atexit handlers run as before, and the command has closed its
        # files, pools and clusters itself (only cycles of garbage are left to the system)
        gc.freeze()


if __name__ == "__main__":
    sys.exit(main())
