"""Killed and concurrent runs (issue 15): the output folder holds exactly the previous
run or exactly the new one, never a mix; SIGINT/SIGTERM exit with one line, no traceback."""

import os
import random
import signal
import subprocess
import sys
import time

import pytest

SIZES = (10, 20, 40, 80, 160, 320)
CURVE = (0.97, 0.9, 0.7, 0.35, 0.1, 0.02)


def _points(path, shift):
    rows = [f"E{k},{s * (1 + 0.1 * k + shift)},{p}" for k in range(3) for s, p in zip(SIZES, CURVE)]
    path.write_text("experiment,size,partition_fine\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def _fit(points, out):
    argv = [sys.executable, "-m", "tromplab", "fit", str(points), "-o", str(out), "--bootstrap", "100", "--no-figures"]
    return subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _content(out):
    return {p.name: p.read_bytes() for p in sorted(out.iterdir()) if not p.name.startswith(".")}


def _staging_left(folder):
    return [p for p in folder.iterdir() if p.name.startswith(".out.tmp-") or p.name.startswith(".out.old-")]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Contents of a complete run on the old and on the new points."""
    folder = tmp_path_factory.mktemp("reference")
    contents = []
    for shift in (0.0, 0.5):
        out = folder / f"out{shift}"
        process = _fit(_points(folder / f"p{shift}.csv", shift), out)
        assert process.wait(timeout=120) == 0, process.stderr.read()
        contents.append(_content(out))
    assert contents[0] != contents[1]
    return contents


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_a_killed_run_leaves_the_previous_or_the_new_outputs_never_a_mix(tmp_path, runs, signum):
    old, new = runs
    generator = random.Random(int(signum))
    # from 2 s on: tromplab is imported (a SIGINT while Python imports numpy/pandas still prints
    # Python's own traceback, before any tromplab code runs; see docs/reliability.md)
    for delay in sorted(generator.uniform(2.0, 4.0) for _ in range(1)):
        out = tmp_path / "out"
        old_points, new_points = _points(tmp_path / "old.csv", 0.0), _points(tmp_path / "new.csv", 0.5)
        assert _fit(old_points, out).wait(timeout=120) == 0  # also cleans what the previous kill left
        assert _content(out) == old
        process = _fit(new_points, out)
        time.sleep(delay)
        process.send_signal(signum)
        code = process.wait(timeout=120)
        stderr = process.stderr.read()
        assert _content(out) in (old, new), f"mixed outputs after {signum!r} at {delay:.2f} s"
        if code == 0:
            assert _content(out) == new  # finished before the signal
            continue
        assert _content(out) == old
        if signum == signal.SIGKILL:
            assert code == -signal.SIGKILL
        else:
            assert "Traceback" not in stderr
            assert code in (130, 143, -int(signum)), stderr  # -signum: killed before the handler was installed
            if code in (130, 143):
                assert code == (130 if signum == signal.SIGINT else 143)
                assert len(stderr.strip().splitlines()) == 1, stderr
                assert not _staging_left(tmp_path)
    # a following run cleans anything a SIGKILL left and gives exactly the new outputs
    assert _fit(_points(tmp_path / "new.csv", 0.5), tmp_path / "out").wait(timeout=120) == 0
    assert _content(tmp_path / "out") == new
    assert not _staging_left(tmp_path)


@pytest.mark.slow
def test_two_concurrent_runs_into_one_folder_leave_one_complete_run(tmp_path, runs):
    old, new = runs
    out = tmp_path / "out"
    first = _fit(_points(tmp_path / "old.csv", 0.0), out)
    second = _fit(_points(tmp_path / "new.csv", 0.5), out)
    assert first.wait(timeout=120) == 0, first.stderr.read()
    assert second.wait(timeout=120) == 0, second.stderr.read()  # the lock serialises the swaps
    assert _content(out) in (old, new)
    assert not _staging_left(tmp_path)
    assert os.path.exists(tmp_path / ".out.lock")
