"""The fleet store against bad logs, bad paths and runaway requests: a poison log is a
failure row with its file and reason while the others are stored; a run is its content,
not its bytes; FIFOs, /dev/null, newlines in ids, naive ISO times, 500 workers, an HTTP
server as the scheduler and a fleet beyond the disk are each one line, at once."""

from __future__ import annotations

import datetime as dt
import http.server
import os
import sys
import threading
import time
from pathlib import Path

import duckdb
import pytest

from bench.cli import main

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "unit"))
from cli_errors import one_line  # noqa: E402
from log_frames import run, write_log  # noqa: E402


def log(path: Path, n: int = 30, t0: float = 1.7e9) -> Path:
    msgs = run(n)
    for m in msgs:
        m.timestamp = round(m.timestamp - 1000.0 + t0, 6)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_log(str(path), msgs)
    return path


def rows(db: Path, sql: str) -> list[tuple]:
    con = duckdb.connect(str(db), read_only=True)
    try:
        return con.execute(sql).fetchall()
    finally:
        con.close()


def test_a_poison_log_is_a_failure_row_and_the_others_are_stored(tmp_path, capsys):
    """Timestamps 1e12 s ahead stopped the ingest with `ValueError: year 33658 is out of
    range`, no file named, every rerun the same."""
    d = tmp_path / "A1"
    log(d / "a.log", t0=1.7e9)
    bad = log(d / "b.log", t0=1.7e9 + 86400)
    lines = bad.read_text().splitlines(keepends=True)
    for k in (0, 7, 12):                        # the first line among them
        ts, rest = lines[k].split(")", 1)
        lines[k] = f"({float(ts[1:]) + 1e12:.6f}){rest}"
    bad.write_text("".join(lines))
    log(d / "c.log", t0=1.7e9 + 2 * 86400)
    db = tmp_path / "f.duckdb"
    assert main(["fleet", "ingest", str(d), "--db", str(db), "--workers", "1"]) == 0
    out = capsys.readouterr()
    assert "3 files: 0 already stored, 2 runs stored, 1 failed" in out.out
    assert "b.log" in out.err and "no date of the years 1970-9999" in out.err
    assert f"{d / 'b.log'}: {d / 'b.log'}" not in out.err    # the file named once
    fails = rows(db, "SELECT path, error FROM failures")
    assert len(fails) == 1 and fails[0][0].endswith("b.log") and "1970-9999" in fails[0][1]
    assert main(["fleet", "ingest", str(d), "--db", str(db), "--workers", "1"]) == 0
    again = capsys.readouterr().out              # the poison log is not counted as stored
    assert ("3 files: 3 already stored (1 of them failed before: table `failures`, delete a "
            "row to retry), 0 runs stored, 0 failed") in again


def test_copies_with_crlf_or_a_trailing_blank_line_are_one_run(tmp_path, capsys):
    """Copies of one log with CRLF line ends or a trailing blank line were stored as
    three tests, and the usage tripled."""
    a = log(tmp_path / "A1" / "a.log")
    text = a.read_bytes()
    (tmp_path / "A1" / "crlf.log").write_bytes(text.replace(b"\n", b"\r\n"))
    (tmp_path / "A1" / "blank.log").write_bytes(text + b"\n\n")
    (tmp_path / "A1" / "spaces.log").write_bytes(text.replace(b" ", b"  "))
    db = tmp_path / "f.duckdb"
    assert main(["fleet", "ingest", str(tmp_path / "A1"), "--db", str(db),
                 "--workers", "1"]) == 0
    assert "4 files: 3 already stored, 1 runs stored, 0 failed" in capsys.readouterr().out
    assert rows(db, "SELECT count(*) FROM runs") == [(1,)]
    from bench.fleet.ingest import digest
    other = log(tmp_path / "B" / "b.log", n=31)
    assert digest(other) != digest(a)
    assert digest(a) == __import__("hashlib").sha256(text).hexdigest()   # canonical already


@pytest.mark.parametrize("special", ["fifo", "/dev/null"])
def test_a_fifo_or_dev_null_as_the_path_is_one_line_at_once(tmp_path, capsys, special):
    """A FIFO or /dev/null as the ingest PATH exited 0 with "0 files"."""
    path = tmp_path / "pipe" if special == "fifo" else Path(special)
    if special == "fifo":
        os.mkfifo(path)
    t0 = time.monotonic()
    rc = main(["fleet", "ingest", str(path), "--db", str(tmp_path / "f.duckdb")])
    one_line(capsys, rc, str(path), "not a log file or a directory")
    assert time.monotonic() - t0 < 5 and not (tmp_path / "f.duckdb").exists()


def test_a_newline_in_an_actuator_id_cannot_forge_a_status_line(tmp_path, capsys):
    from bench.bus.logs import load_trace
    tr = load_trace(log(tmp_path / "x.log"))
    tr.meta["actuator_id"] = "A1\nEMA-9999  9  2026-01-01 00:00  HEALTHY"
    tr.meta["run_time"] = "2026-01-05T08:00:00"             # naive ISO: UTC
    tr.save(tmp_path / "t.npz")
    db = tmp_path / "f.duckdb"
    assert main(["fleet", "ingest", str(tmp_path / "t.npz"), "--db", str(db),
                 "--workers", "1"]) == 0
    capsys.readouterr()
    assert main(["fleet", "status", "--db", str(db)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2 and lines[1].startswith("A1\\nEMA-9999")
    rc = main(["fleet", "ingest", str(tmp_path / "t.npz"), "--db", str(db), "--actuator",
               "A\nB"])
    one_line(capsys, rc, "--actuator")


def test_a_naive_iso_run_time_is_utc_whatever_the_local_zone(tmp_path, capsys, monkeypatch):
    """A naive ISO `run_time` was read in local time while `--as-of` reads UTC."""
    from bench.bus.logs import load_trace
    tr = load_trace(log(tmp_path / "x.log"))
    tr.meta["run_time"] = "2026-01-05T08:00:00"
    tr.save(tmp_path / "t.npz")
    monkeypatch.setenv("TZ", "America/New_York")
    time.tzset()
    try:
        db = tmp_path / "f.duckdb"
        assert main(["fleet", "ingest", str(tmp_path / "t.npz"), "--db", str(db),
                     "--actuator", "A1", "--workers", "1"]) == 0
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()
    assert rows(db, "SELECT run_time FROM runs") == [(dt.datetime(2026, 1, 5, 8, 0),)]
    capsys.readouterr()
    assert main(["fleet", "status", "--db", str(db), "--as-of", "2026-01-05T07:59"]) == 0
    assert "no runs in the store up to" in capsys.readouterr().out


def test_workers_beyond_the_cores_are_refused_in_one_line(tmp_path, capsys):
    """`--workers 500` on 2 cores started 500 processes."""
    log(tmp_path / "A1" / "a.log")
    t0 = time.monotonic()
    for argv in (["fleet", "ingest", str(tmp_path / "A1"), "--db", str(tmp_path / "f.duckdb")],
                 ["fleet", "synth", "--actuators", "1", "--days", "1", "--out",
                  str(tmp_path / "s")],
                 ["hums", "sweep"], ["gap", str(tmp_path / "A1" / "a.log")]):
        rc = main([*argv, "--workers", "500"])
        one_line(capsys, rc, "--workers 500", "core")
    assert time.monotonic() - t0 < 10
    assert not (tmp_path / "f.duckdb").exists() and not (tmp_path / "s").exists()


@pytest.fixture
def http_server():
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    th = threading.Thread(target=srv.serve_forever, daemon=True)
    th.start()
    yield f"tcp://127.0.0.1:{srv.server_address[1]}"
    srv.shutdown()
    srv.server_close()


def test_an_http_server_as_the_scheduler_is_one_line_within_seconds(tmp_path, capsys,
                                                                      http_server):
    """A --scheduler that is an HTTP server said "(timed out)" after 43 s; fleet synth
    with an unreachable scheduler left empty actuator folders."""
    out = tmp_path / "s"
    for addr, word in ((http_server, "is not a Dask scheduler"),
                       ("tcp://127.0.0.1:9", "cannot reach")):
        t0 = time.monotonic()
        rc = main(["fleet", "synth", "--actuators", "2", "--days", "2", "--out", str(out),
                   "--scheduler", addr])
        one_line(capsys, rc, addr, word)
        assert time.monotonic() - t0 < 25 and not out.exists()   # the probe waits 5 s
    from bench import BenchError
    from bench.fleet.synth import synth
    with pytest.raises(BenchError, match="cannot reach"):
        synth(2, 2, out, scheduler="tcp://127.0.0.1:9", progress=False)
    assert not out.exists()


def test_a_fleet_beyond_the_disk_or_memory_is_refused_up_front(tmp_path, capsys,
                                                                monkeypatch):
    """`fleet synth --actuators 100000 --days 100000` grew memory at 0.5 GB/s."""
    out = tmp_path / "s"
    t0 = time.monotonic()
    rc = main(["fleet", "synth", "--actuators", "100000", "--days", "100000", "--out",
               str(out)])
    one_line(capsys, rc, "10000000000 logs", "free")
    assert time.monotonic() - t0 < 5 and not out.exists()
    from bench import BenchError
    from bench.fleet import synth as S
    free = __import__("shutil").disk_usage(tmp_path).free
    n = int(free // S.LOG_BYTES // 1000) + 2          # just beyond the disk, 1000 days
    with pytest.raises(BenchError, match="free"):
        S.check_size(n, 1000, out)
    S.check_size(2, 3, out)
    import bench.signals.trace as T
    monkeypatch.setattr(T, "memory_available", lambda: 10 * S.MEMORY_PER_LOG)
    with pytest.raises(BenchError, match="memory"):
        S.check_size(5, 5, out)


def test_the_log_size_the_bound_assumes_is_a_written_logs(tmp_path):
    from bench.fleet import synth as S
    path = tmp_path / "A" / "x.log"
    S._job((str(path), S.wear_at(S.draw_fleet(1, 2, 0, "time")[0], 0), 1, 1.7e9, "A"))
    assert abs(path.stat().st_size - S.LOG_BYTES) < 0.01 * S.LOG_BYTES


def test_a_failed_table_is_named_once_and_counted_as_failed_on_a_rerun(tmp_path, capsys):
    """A table that is no trace printed its file name twice ("bad.csv: bad.csv: ..."), and
    on a rerun it was counted among the logs already stored, as if it had been stored."""
    d = tmp_path / "A1"
    d.mkdir()
    bad = d / "bad.csv"
    bad.write_text("\x00\x01garbage")
    db = tmp_path / "f.duckdb"
    assert main(["fleet", "ingest", str(bad), "--db", str(db), "--workers", "1"]) == 0
    err = capsys.readouterr().err
    assert f"failed: {bad}: " in err and f"{bad}: {bad}" not in err and "bad.csv: bad.csv" not in err
    assert main(["fleet", "ingest", str(bad), "--db", str(db), "--workers", "1"]) == 0
    assert "1 already stored (1 of them failed before" in capsys.readouterr().out


def test_an_unreadable_log_is_a_failure_row_and_counted_as_failed_on_a_rerun(tmp_path,
                                                                             monkeypatch):
    """A log whose bytes cannot be read (no digest of its content) is a failure row named by
    its path, skipped on a rerun and counted there among the earlier failures."""
    import bench.fleet.ingest as I
    path = log(tmp_path / "A1" / "a.log")
    real = I.digest

    def refused(f):
        if f.name == "a.log":
            raise PermissionError(13, "Permission denied")
        return real(f)

    monkeypatch.setattr(I, "digest", refused)
    db = tmp_path / "f.duckdb"
    first = I.ingest([str(path)], db, 1, progress=False)
    assert (first.failed, first.stored, first.failed_before) == (1, 0, 0)
    assert first.failures == [(str(path), "cannot be read (Permission denied)")]
    again = I.ingest([str(path)], db, 1, progress=False)
    assert (again.skipped, again.failed, again.failed_before) == (1, 0, 1)


def test_a_synthetic_fleet_is_not_mixed_into_another_fleet_or_a_rigs_logs(tmp_path,
                                                                          capsys):
    """A second `fleet synth` with another seed into the same folder added its logs to the
    first fleet's and replaced its fleet-truth.json, so an ingest of the folder read two
    fleets under one set of actuator ids against one fleet's truth."""
    out = tmp_path / "fl"
    args = ["fleet", "synth", "--actuators", "1", "--days", "1", "--out", str(out),
            "--workers", "1"]
    assert main([*args, "--seed", "1"]) == 0
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    capsys.readouterr()
    one_line(capsys, main([*args, "--seed", "2"]), "another synthetic fleet", "seed 1")
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert main([*args, "--seed", "1"]) == 0                 # the same fleet again: its own
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    rig = tmp_path / "rig"
    log(rig / "EMA-0000" / "run1.log")
    capsys.readouterr()
    one_line(capsys, main([*args[:7], str(rig), "--workers", "1"]), "run1.log",
             "this fleet would not write")
    assert sorted(p.name for p in rig.rglob("*")) == ["EMA-0000", "run1.log"]


def test_a_folder_of_compressed_and_vector_logs_is_ingested_with_their_bus_time(tmp_path,
                                                                                capsys):
    """A directory search took only .log files and trace tables: a fleet's Vector .blf
    logs, or candump logs kept as .log.gz, were "a directory with no log in it"; a .blf
    given by name was dated by the file's modification time, not its bus time."""
    import gzip

    import can
    d = tmp_path / "A7"
    a = log(d / "a.log", t0=1.7e9)
    (d / "a.log.gz").write_bytes(gzip.compress(a.read_bytes()))        # the same run
    a.unlink()
    b = log(tmp_path / "b.log", t0=1.7e9 + 86400)
    with can.Logger(str(d / "b.blf")) as w:
        for msg in can.LogReader(str(b)):
            w.on_message_received(msg)
    os.utime(d / "b.blf", (1.0e9, 1.0e9))
    db = tmp_path / "f.duckdb"
    assert main(["fleet", "ingest", str(d), "--db", str(db), "--workers", "1"]) == 0
    assert "2 files: 0 already stored, 2 runs stored, 0 failed" in capsys.readouterr().out
    got = rows(db, "SELECT path, epoch(run_time) FROM runs ORDER BY run_time")
    assert [Path(p).name for p, _ in got] == ["a.log.gz", "b.blf"]
    assert abs(got[0][1] - 1.7e9) < 60 and abs(got[1][1] - (1.7e9 + 86400)) < 60
    log(tmp_path / "plain" / "a.log", t0=1.7e9)                  # a.log.gz, uncompressed
    assert main(["fleet", "ingest", str(tmp_path / "plain"), "--db", str(db), "--actuator",
                 "A7", "--workers", "1"]) == 0
    assert "1 files: 1 already stored, 0 runs stored" in capsys.readouterr().out


def test_a_truncated_compressed_log_is_a_failure_row_and_the_others_are_stored(tmp_path,
                                                                               capsys):
    """The digest of a cut .log.gz raised EOFError ("Compressed file ended before the
    end-of-stream marker was reached") and stopped the whole ingest."""
    import gzip
    d = tmp_path / "A8"
    good = log(d / "a.log", t0=1.7e9)
    data = gzip.compress(log(tmp_path / "b.log", t0=1.7e9 + 86400).read_bytes())
    (d / "b.log.gz").write_bytes(data[: len(data) // 2])
    db = tmp_path / "f.duckdb"
    assert main(["fleet", "ingest", str(d), "--db", str(db), "--workers", "1"]) == 0
    out = capsys.readouterr()
    assert "2 files: 0 already stored, 1 runs stored, 1 failed" in out.out
    assert "b.log.gz: cannot decompress" in out.err and "complete .gz file" in out.err
    assert [Path(p).name for (p,) in rows(db, "SELECT path FROM runs")] == [good.name]
