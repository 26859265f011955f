"""Dask as users run it beyond one machine: a scheduler and two workers in processes of their
own, and ``tromplab fit --scheduler tcp://...`` writes what ``--jobs 1`` writes, byte for byte,
also when the results stream to disk (the workers write their chunks' files themselves)."""

import filecmp
import json
import os
import subprocess
import sys
import time

import pytest

from tromplab._synthetic import synthetic
from tromplab.cli import main

pytest.importorskip("distributed", reason="the dask extra (pip install 'tromplab[dask]') is not installed")


def _start(*arguments, log):
    # the same interpreter, so the workers unpickle the same tromplab as the client
    return subprocess.Popen([sys.executable, "-m", "dask", *arguments], stdout=log, stderr=subprocess.STDOUT)


@pytest.fixture
def cluster(tmp_path):
    """A scheduler on 127.0.0.1 and two single-threaded workers, torn down whatever happens."""
    scheduler_file = tmp_path / "scheduler.json"
    log = open(tmp_path / "cluster.log", "w")
    processes = [_start("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                        "--scheduler-file", str(scheduler_file), log=log)]  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert scheduler_file.exists(), (tmp_path / "cluster.log").read_text()
        address = json.loads(scheduler_file.read_text())["address"]
        for _ in range(2):
            processes.append(_start("worker", "--scheduler-file", str(scheduler_file), "--nworkers", "1", "--nthreads", "1",
                                    "--no-dashboard", "--host", "127.0.0.1", log=log))  # fmt: skip
        from distributed import Client

        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for process in processes:
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
        log.close()


@pytest.mark.slow
def test_fit_on_a_cluster_of_separate_processes_writes_what_one_process_writes(tmp_path, cluster, monkeypatch, caplog):
    points = tmp_path / "points.csv"
    frames = [synthetic(seed, weighted=False).to_frame() for seed in range(70)]  # two chunks of 64 experiments
    import pandas as pd

    from tromplab.parallel import streaming

    pd.concat(frames, ignore_index=True).to_csv(points, index=False)
    options = ["--figures", "none", "--ci", "0.9", "--formulas", "plitt,lognormal,shuvalov", "-q"]
    assert main(["fit", str(points), "-o", str(tmp_path / "local"), "--jobs", "1", *options]) == 0
    assert main(["fit", str(points), "-o", str(tmp_path / "cluster"), "--scheduler", cluster, *options]) == 0
    monkeypatch.setattr(streaming, "STREAM_THRESHOLD", 10)  # the results stream to disk from 10 experiments
    with caplog.at_level("INFO", logger="tromplab.workbench"):
        assert main(["fit", str(points), "-o", str(tmp_path / "streamed"), "--scheduler", cluster, *options]) == 0
    assert "streamed to" in caplog.text and "workers write the files" in caplog.text
    names = sorted(p.name for p in (tmp_path / "local").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "streamed").iterdir())
    for name in ("fits.csv", "ranking.csv", "averages.csv"):
        assert filecmp.cmp(tmp_path / "local" / name, tmp_path / "cluster" / name, shallow=False), name
    for name in names:
        assert filecmp.cmp(tmp_path / "local" / name, tmp_path / "streamed" / name, shallow=False), name
    assert os.path.getsize(tmp_path / "cluster" / "fits.csv") > 0


@pytest.mark.slow
def test_the_local_cluster_runs_its_workers_with_tromplab_s_dask_settings():
    """Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536, which made glibc map and
    unmap every numpy array above 64 KiB: a chunk of fits ran 1.5 x slower on a Dask worker
    than in process. The cluster of ``dask="local"`` starts its workers without it, without the
    statistical profiler and with the slower health checks of ``DASK_WORKER_CONFIG``."""
    import dask

    from tromplab.workbench import DASK_WORKER_CONFIG, dask_client

    def settings(dask_worker):
        found = {key: dask.config.get(key) for key in DASK_WORKER_CONFIG if "pre-spawn" not in key}
        return os.environ.get("MALLOC_TRIM_THRESHOLD_"), "profile" in dask_worker.periodic_callbacks, found

    with dask_client(dask="local") as client:
        found = client.run(settings)
    expected = {key: value for key, value in DASK_WORKER_CONFIG.items() if "pre-spawn" not in key}
    assert len(found) == 2
    assert all(value == (None, False, expected) for value in found.values()), found


def test_the_documented_dask_settings_are_those_of_the_local_cluster():
    """docs/performance.md gives the settings of DASK_WORKER_CONFIG as a Dask configuration file
    and as environment variables; both must say what the local cluster uses."""
    import re
    from pathlib import Path

    import dask
    import yaml

    from tromplab.workbench import DASK_WORKER_CONFIG

    text = (Path(__file__).parents[1] / "docs" / "performance.md").read_text(encoding="utf-8")
    block = re.search(r"```yaml\n# ~/.config/dask/tromplab.yaml\n(.*?)```", text, re.S).group(1)
    documented = {}

    def flatten(tree, prefix):
        for key, value in tree.items():
            if isinstance(value, dict):
                flatten(value, f"{prefix}{key}.")
            else:
                documented[f"{prefix}{key}"] = value

    flatten(yaml.safe_load(block), "")
    assert documented == DASK_WORKER_CONFIG
    variables = dict(re.findall(r"`(DASK_[A-Z_]+)=([^`]+)`", text))
    from_environment = dask.config.collect_env(variables)
    for key, value in DASK_WORKER_CONFIG.items():
        if not key.startswith("distributed.nanny."):
            assert dask.config.get(key, config=from_environment) == value, key
