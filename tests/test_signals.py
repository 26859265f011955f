"""Killed and concurrent runs: the output folder holds exactly the previous
run or exactly the new one, never a mix; SIGINT/SIGTERM exit with one line, no traceback,
at any moment from the start of the process on."""

import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tromplab.cli import main
from tromplab.output import outputs
from tromplab.output.outputs import MANIFEST, SWAP_PAUSE_VARIABLE, clean_stale, lock_folder, lock_path

SIZES = (10, 20, 40, 80, 160, 320)
CURVE = (0.97, 0.9, 0.7, 0.35, 0.1, 0.02)
REPOSITORY = Path(__file__).resolve().parents[1]
# what the installed ``tromplab`` console script runs (pyproject [project.scripts]), and ``python -m
# tromplab``: both go through tromplab._launch; PYTHONPATH finds this checkout's tromplab
SCRIPT = [sys.executable, "-c", "import sys; from tromplab._launch import main; sys.exit(main())"]
MODULE = [sys.executable, "-m", "tromplab"]
LAUNCH = SCRIPT


def _points(path, shift):
    rows = [f"E{k},{s * (1 + 0.1 * k + shift)},{p}" for k in range(3) for s, p in zip(SIZES, CURVE)]
    path.write_text("experiment,size,partition_fine\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def _as_in_a_terminal():
    # the child of a test run started in the background (``cmd &``, nohup) inherits SIGINT
    # ignored, and tromplab keeps a signal ignored on purpose; a user's Ctrl-C reaches a
    # process whose SIGINT is at its default, so the children start that way
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start(arguments, launch=LAUNCH, **environment):
    env = {**os.environ, "PYTHONPATH": str(REPOSITORY), **environment}
    return subprocess.Popen(
        launch + arguments,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=_as_in_a_terminal,
    )


def _fit(points, out, **environment):
    # 20 bootstrap resamples: about a second of work to land a signal in
    return _start(["fit", str(points), "-o", str(out), "--bootstrap", "20", "--no-figures"], **environment)


def _content(out):
    return {p.name: p.read_bytes() for p in sorted(out.iterdir()) if not p.name.startswith(".")}


def _staging_left(folder):
    return [p for p in folder.iterdir() if p.name.startswith(".out.tmp-") or p.name.startswith(".out.old-")]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Folder of a complete run on the old points, and the contents of the old and new runs."""
    folder = tmp_path_factory.mktemp("reference")
    for shift in (0.0, 0.5):  # one after the other: the outputs are compared byte for byte with later runs
        process = _fit(_points(folder / f"p{shift}.csv", shift), folder / f"out{shift}")
        assert process.wait(timeout=120) == 0, process.stderr.read()
    old, new = _content(folder / "out0.0"), _content(folder / "out0.5")
    assert old != new
    return folder / "out0.0", old, new


def _previous_run(tmp_path, runs):
    """``tmp_path/out`` holding the old run (manifest included), and the new points."""
    old_folder, old, _ = runs
    shutil.copytree(old_folder, tmp_path / "out")
    assert _content(tmp_path / "out") == old
    return tmp_path / "out", _points(tmp_path / "new.csv", 0.5)


def _check_killed(process, signum, out, old, new):
    code = process.wait(timeout=120)
    stderr = process.stderr.read()
    assert "Traceback" not in stderr
    assert _content(out) in (old, new), f"mixed outputs after {signum!r}"
    if code == 0:
        assert _content(out) == new  # finished before the signal
        return code
    # a signal after the swap (while the tables are printed) leaves the complete new run
    content = _content(out)
    if signum == signal.SIGKILL:
        assert code == -signal.SIGKILL
        clean_stale(out)  # what the next run into the folder does first
    else:
        if code != -signum:  # -signum: the signal came as the interpreter exited, after the run
            assert code == (130 if signum == signal.SIGINT else 143), stderr
            assert len(stderr.strip().splitlines()) == 1, stderr
    assert _content(out) == content
    assert not _staging_left(out.parent)
    return code


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_a_run_killed_while_working_leaves_the_previous_or_the_new_outputs(tmp_path, runs, signum):
    _, old, new = runs
    out, new_points = _previous_run(tmp_path, runs)
    process = _fit(new_points, out)
    time.sleep(random.Random(int(signum)).uniform(0.3, 2.0))  # importing, reading, fitting or bootstrapping
    process.send_signal(signum)
    _check_killed(process, signum, out, old, new)


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_a_run_killed_just_before_the_swap_leaves_the_previous_outputs(tmp_path, runs, signum):
    _, old, new = runs
    out, new_points = _previous_run(tmp_path, runs)
    process = _fit(new_points, out, **{SWAP_PAUSE_VARIABLE: "60"})
    deadline = time.monotonic() + 60
    while not any((staging / MANIFEST).exists() for staging in tmp_path.glob(".out.tmp-*")):  # all staged
        assert process.poll() is None, process.stderr.read()
        assert time.monotonic() < deadline
        time.sleep(0.05)
    time.sleep(0.3)  # the folder is locked and the previous run's other files linked in: now in the pause
    process.send_signal(signum)
    assert _check_killed(process, signum, out, old, new) != 0
    assert _content(out) == old


def test_the_swap_pause_hook_is_off_unless_set_to_a_positive_number(monkeypatch):
    from tromplab.output import outputs

    slept = []
    monkeypatch.setattr(outputs.time, "sleep", slept.append)
    for value in (None, "", "no", "nan", "-1", "0"):
        if value is None:
            monkeypatch.delenv(SWAP_PAUSE_VARIABLE, raising=False)
        else:
            monkeypatch.setenv(SWAP_PAUSE_VARIABLE, value)
        outputs._pause_for_tests()
    assert slept == []
    monkeypatch.setenv(SWAP_PAUSE_VARIABLE, "1e9")
    outputs._pause_for_tests()
    assert slept == [60.0]


def _catches_sigterm(pid) -> bool:
    """Whether the process has a SIGTERM handler (Linux /proc), i.e. tromplab._launch runs."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigCgt:"):
            return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)
    return False


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads the signal mask from /proc (Linux)")
@pytest.mark.parametrize("launch", [SCRIPT, MODULE], ids=["script", "python-m"])
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_during_start_up_imports_prints_one_line_and_no_traceback(tmp_path, signum, launch):
    """Sent as soon as the entry point runs, while numpy/pandas are imported (about a second).

    The first ~20 ms belong to Python's own start-up (``site``), before any tromplab code:
    a SIGINT there is Python's (see docs/reliability.md); the test starts after it."""
    points = _points(tmp_path / "p.csv", 0.0)
    for delay in (0.0, 0.1, 0.3):
        process = _start(["fit", str(points), "-o", str(tmp_path / "out"), "--no-figures"], launch)
        deadline = time.monotonic() + 30
        while not _catches_sigterm(process.pid):
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.001)
        time.sleep(delay)
        process.send_signal(signum)
        code = process.wait(timeout=60)
        stderr = process.stderr.read()
        assert "Traceback" not in stderr, (delay, stderr)
        assert code == (130 if signum == signal.SIGINT else 143), (delay, stderr)
        assert len(stderr.strip().splitlines()) == 1, stderr
        assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_two_concurrent_runs_into_one_folder_leave_one_complete_run(tmp_path, runs):
    _, old, new = runs
    out = tmp_path / "out"
    first = _fit(_points(tmp_path / "old.csv", 0.0), out)
    second = _fit(_points(tmp_path / "new.csv", 0.5), out)
    assert first.wait(timeout=120) == 0, first.stderr.read()
    assert second.wait(timeout=120) == 0, second.stderr.read()  # the lock serialises the swaps
    assert _content(out) in (old, new)
    assert not _staging_left(tmp_path)
    assert not list(tmp_path.glob("*.lock")) and not list(tmp_path.glob(".*.lock"))  # the lock lives elsewhere
    assert lock_path(out).exists()


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_while_the_interpreter_exits_gives_one_line_and_no_traceback(signum):
    # after the command has returned, Python still runs the atexit handlers (process pools, Dask):
    # a Ctrl-C there used to print "Exception ignored in atexit callback" with a traceback
    script = (
        "import atexit, os, signal, sys, time\n"
        "from tromplab import _launch, cli\n"
        "cli.main = lambda on_start: 0\n"
        f"atexit.register(lambda: (os.kill(os.getpid(), {int(signum)}), time.sleep(5)))\n"
        "sys.exit(_launch.main())\n"
    )
    env = {**os.environ, "PYTHONPATH": str(REPOSITORY)}
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=60, preexec_fn=_as_in_a_terminal
    )
    assert "Traceback" not in done.stderr
    assert done.returncode == (130 if signum == signal.SIGINT else 143), done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "finished" in done.stderr


def _interrupting(function, signum):
    """``function`` that sends ``signum`` to this process while it runs (delivered in the main thread)."""

    def wrapped(*args, **kwargs):
        os.kill(os.getpid(), signum)
        return function(*args, **kwargs)

    return wrapped


@pytest.mark.parametrize(
    "signum, code, what", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated (SIGTERM)")]
)
@pytest.mark.slow
def test_a_signal_during_the_swap_waits_for_it_and_says_the_new_results_were_written(
    tmp_path, runs, monkeypatch, capsys, signum, code, what
):
    _, old, new = runs
    out, new_points = _previous_run(tmp_path, runs)
    monkeypatch.setattr(outputs, "_swap_into_place", _interrupting(outputs._swap_into_place, signum))
    assert main(["fit", str(new_points), "-o", str(out), "--bootstrap", "20", "--no-figures"]) == code
    content = _content(out)  # the swap was held together: the whole new run, and the interrupt after it
    assert content.keys() == new.keys() and content["fits.csv"] != old["fits.csv"]
    assert content["fits.csv"].splitlines()[1:2] != old["fits.csv"].splitlines()[1:2]
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"tromplab: {what} after the new results were written, complete, to {out}"]


def test_a_late_sigint_after_the_outputs_ends_with_its_message_and_130(tmp_path, runs, monkeypatch, capsys):
    from tromplab.cli import fit as fit_command

    out, new_points = _previous_run(tmp_path, runs)
    monkeypatch.setattr(fit_command, "_print_written", _interrupting(fit_command._print_written, signal.SIGINT))
    assert main(["fit", str(new_points), "-o", str(out), "--no-figures"]) == 130
    assert capsys.readouterr().err.strip().splitlines() == [
        f"tromplab: interrupted after the new results were written, complete, to {out}"
    ]
    assert main(["fit", str(new_points), "-o", str(tmp_path / "other"), "--alpha", "2"]) == 2  # the record is per command
    monkeypatch.setattr(fit_command, "_print_fits", _interrupting(fit_command._print_fits, signal.SIGINT))
    assert main(["fit", str(new_points), "-o", str(tmp_path / "third"), "--no-figures"]) == 130
    assert f"complete, to {tmp_path / 'third'}" in capsys.readouterr().err


def _lock_files(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.name.endswith(".lock"))


@pytest.mark.parametrize(
    "argv",
    [
        ["fit", "{points}", "-o", "out", "--no-figures"],
        ["fit", "{points}", "--no-figures"],  # the default folder, results/, in the working directory
        ["points", "{lab}", "-o", "pts.csv"],
        ["points", "{lab}", "-o", "sub/pts.csv"],
        ["report", "{points}", "-o", "report.html"],
        ["circuit", "{flowsheet}", "{survey}", "-o", "circ", "--no-figures"],
    ],
    ids=["fit", "fit-default", "points", "points-sub", "report", "circuit"],
)
@pytest.mark.slow
def test_successful_runs_leave_no_lock_file_in_the_users_folders(tmp_path, monkeypatch, argv):
    from .conftest import DATASETS, LAB_CLASS_HEADER, LAB_CLASS_ROWS

    monkeypatch.chdir(tmp_path)
    files = {
        "points": _points(tmp_path / "p.csv", 0.0),
        "lab": tmp_path / "lab.csv",
        "flowsheet": DATASETS / "circuit_example_flowsheet.csv",
        "survey": DATASETS / "circuit_example_survey.csv",
    }
    files["lab"].write_text(LAB_CLASS_HEADER + "\n".join(LAB_CLASS_ROWS) + "\n")
    assert main([part.format(**files) for part in argv]) in (0, 3)
    assert _lock_files(tmp_path) == []
    assert lock_folder().stat().st_mode & 0o777 == 0o700


def test_the_lock_folder_is_refused_when_others_can_enter_it(tmp_path, monkeypatch):
    from tromplab.errors import OutputError

    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    folder = tmp_path / f"tromplab-locks-{os.getuid()}"
    folder.mkdir(mode=0o777)
    folder.chmod(0o777)
    with pytest.raises(OutputError, match="not a private folder"):
        lock_folder()
    folder.chmod(0o700)
    assert lock_path(tmp_path / "out").parent == folder
    assert lock_path(tmp_path / "out") == lock_path(tmp_path / "x" / ".." / "out")
