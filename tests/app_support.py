"""Shared by the app's tests: the command line run in a folder, files compared, the app's
client polled until its run ends."""

from __future__ import annotations

import contextlib
import io
import os
import time
import zipfile
from pathlib import Path

#: Tromp points of two experiments whose names would be markup, script or a formula if a page
#: or a spreadsheet read them as such (sizes in um, partitions of a smooth curve with noise).
HOSTILE_NAMES = ("<img src=x onerror=\"window.__xss='img'\">", "<script>window.__xss='script'</script>")
POINTS = (
    (38.0, 0.858), (50.4, 0.816), (66.9, 0.797), (88.7, 0.732), (117.6, 0.592),
    (156.0, 0.442), (207.0, 0.297), (274.6, 0.156), (364.3, 0.112), (483.2, 0.101),
)  # fmt: skip


def points_csv(names=HOSTILE_NAMES) -> str:
    """A Tromp-points file of one experiment per name, the second one's partitions shifted."""
    rows = ["experiment,size,partition_fine"]
    for index, name in enumerate(names):
        quoted = '"' + name.replace('"', '""') + '"'
        rows += [f"{quoted},{size},{min(partition + 0.03 * index, 1.0):.3f}" for size, partition in POINTS]
    return "\n".join(rows) + "\n"


def run_cli(folder: Path, arguments: list[str]) -> tuple[int, str]:
    """``tromplab ARGUMENTS`` run in ``folder``: the exit code and standard error."""
    from tromplab.cli import main

    said, here = io.StringIO(), os.getcwd()
    os.chdir(folder)
    try:
        with contextlib.redirect_stderr(said), contextlib.redirect_stdout(io.StringIO()):
            code = main(arguments)
    finally:
        os.chdir(here)
    return code, said.getvalue()


def workbook_parts(data: bytes) -> dict[str, bytes]:
    """The parts of an .xlsx archive, the creation and modification times of its properties
    (``docProps/core.xml``, which openpyxl stamps with the clock: two runs of the command
    differ there and nowhere else) blanked."""
    import re

    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        parts = {name: archive.read(name) for name in archive.namelist()}
    parts["docProps/core.xml"] = re.sub(rb"(<dcterms:(created|modified)[^>]*>)[^<]*", rb"\1", parts["docProps/core.xml"])
    return parts


def zip_members(data: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def assert_same_file(app_bytes: bytes, command_path: Path) -> None:
    """The app's download equals the command's file byte for byte (a workbook: part for part, times aside)."""
    expected = command_path.read_bytes()
    if command_path.suffix == ".xlsx":
        assert workbook_parts(app_bytes) == workbook_parts(expected), command_path.name
    else:
        assert app_bytes == expected, f"{command_path.name} differs from the command's"


def wait_for_run(client, *, timeout: float = 120.0) -> dict:
    """Poll the client's run until it is no longer running; its last state."""
    ends = time.monotonic() + timeout
    while time.monotonic() < ends:
        state = client.get("/api/job").json()
        if state["state"] != "running":
            return state
        time.sleep(0.2)
    raise AssertionError(f"the run did not end within {timeout} s")
