"""`bench hums watch` checks its output files before it opens the bus: a file that holds
something a watch did not write is refused (it was truncated to 0 bytes), a watch's own
rows are appended to, and one that cannot be written gives one line (a second one,
"RemoteBus was not properly shut down", followed it)."""

from __future__ import annotations

import pytest
from bus_helpers import thread_hub
from cli_errors import one_line

from bench.cli import main


@pytest.fixture
def hub():
    with thread_hub() as h:
        yield h


def _watch(hub, *extra: str) -> int:
    return main(["hums", "watch", "--duration", "1", "-i", "remote", "-c", hub.url, *extra])


@pytest.mark.parametrize("flag, name", [("--out", "wt.log"), ("--usage", "usage.json")])
def test_watch_refuses_an_output_that_holds_something(tmp_path, capsys, hub, flag, name):
    """`--out wt.log`, an existing candump log, exited 0 with the log emptied."""
    path = tmp_path / name
    text = "(1000.000000) vcan0 080#01\n" * 1000
    path.write_text(text)
    one_line(capsys, _watch(hub, flag, str(path)), flag, str(path), "is not a watch's",
             "name a new file")
    assert path.read_text() == text


@pytest.mark.parametrize("flag, name, text", [
    ("--out", "rows.csv", "run,period,t_start_s,cp,ci\n1,1,0.0,1.0,1.0\n"),
    ("--usage", "usage.json", '{"runs": [], "actuators": {}}')])
def test_a_watchs_own_file_is_taken_again(tmp_path, capsys, monkeypatch, hub, flag, name,
                                          text):
    """A second watch to the same --out appends its rows (the first one's stay); the
    --usage file a watch rewrites is its own to rewrite."""
    import bench.bus

    def opened(cfg):
        raise bench.BenchError("the bus was opened")
    monkeypatch.setattr(bench.bus, "connect", opened)
    path = tmp_path / name
    path.write_text(text)
    one_line(capsys, _watch(hub, flag, str(path)), "the bus was opened")
    assert path.read_text() == text


def test_watch_takes_an_empty_output(tmp_path, capsys, monkeypatch, hub):
    """An empty --out is new to the watch: the checks let it through to the bus."""
    import bench.bus

    def opened(cfg):
        raise bench.BenchError("the bus was opened")
    monkeypatch.setattr(bench.bus, "connect", opened)
    path = tmp_path / "rows.csv"
    path.write_text("")
    one_line(capsys, _watch(hub, "--out", str(path)), "the bus was opened")


def test_watch_checks_an_unwritable_output_before_the_bus(capsys, monkeypatch, hub):
    """`--out /proc/x.csv` printed "error: /proc/x.csv: No such file or directory", then
    "RemoteBus was not properly shut down": the bus was open when the file failed."""
    import bench.bus

    def opened(cfg):
        raise AssertionError("the bus was opened before --out was checked")
    monkeypatch.setattr(bench.bus, "connect", opened)
    one_line(capsys, _watch(hub, "--out", "/proc/x.csv"), "--out", "/proc/x.csv",
             "not writable")
