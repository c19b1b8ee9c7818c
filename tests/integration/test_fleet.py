"""The fleet end to end: a synthetic fleet (2 actuators x 3 days) -> ingest -> status ->
report -> export, read back with plain duckdb; an ingest killed by SIGKILL mid-way and
run again loses and duplicates nothing."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bench.cli import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    out = tmp_path_factory.mktemp("fleet") / "logs"
    assert main(["fleet", "synth", "--actuators", "2", "--days", "3", "--out", str(out),
                 "--seed", "5", "--workers", "1"]) == 0
    return out


def test_synth_ingest_status_report_export(fleet, tmp_path, capsys):
    logs = sorted(fleet.rglob("*.log"))
    assert [p.parent.name for p in logs] == ["EMA-0000"] * 3 + ["EMA-0001"] * 3
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "x.log").write_text("(1.0) can0 080#\nnot a frame\n")
    db = str(tmp_path / "f.duckdb")
    capsys.readouterr()
    assert main(["fleet", "ingest", str(fleet), str(tmp_path / "broken"), "--db", db,
                 "--workers", "1"]) == 0
    out = capsys.readouterr()
    assert "7 files: 0 already stored, 6 runs stored, 1 failed" in out.out
    assert "x.log" in out.err
    assert main(["fleet", "ingest", str(fleet / "*" / "*.log"), "--db", db]) == 0
    assert "6 files: 6 already stored, 0 runs stored" in capsys.readouterr().out
    assert main(["fleet", "status", "--db", db]) == 0
    table, _, note = capsys.readouterr().out.partition("note: ")
    lines = table.splitlines()
    assert len(lines) == 3 and lines[1].startswith("EMA-0000") and " 3 " in lines[1]
    assert "HEALTHY" in lines[1] and "% of L10" in lines[1]      # usage from the logs
    # an actuator at WARNING or FAILURE with the ground tests' ~0 % of L10: said why
    assert bool(note) == any(lv in lines[2] for lv in ("WARNING", "FAILURE"))
    assert not note or ("time compression" in note and "EMA-0001" in note
                        and "EMA-0000" not in note)
    rep = tmp_path / "rep"
    assert main(["fleet", "report", "--db", db, "--out", str(rep)]) == 0
    page = (rep / "index.html").read_text()
    assert "Inspect this week" in page and "actuators/EMA-0001.html" in page
    assert "x.log" in page                               # the failed log is listed
    assert (rep / "actuators" / "EMA-0000.png").stat().st_size > 5000
    assert "fleet overview" in (rep / "actuators" / "EMA-0000.html").read_text()
    assert main(["fleet", "export", "--db", db, "--out", str(tmp_path / "pq")]) == 0
    # plain duckdb, no bench: the Parquet export and the store itself
    code = ("import sys, duckdb\n"
            "c = duckdb.connect()\n"
            "print(c.execute(\"SELECT count(*), count(DISTINCT actuator_id) FROM "
            f"'{tmp_path / 'pq' / 'runs.parquet'}'\").fetchone())\n"
            f"d = duckdb.connect('{db}', read_only=True)\n"
            "print(d.execute(\"SELECT actuator_id, count(*) FROM runs GROUP BY ALL ORDER BY 1"
            "\").fetchall())\n"
            "print(d.execute(\"SELECT count(*) FROM failures\").fetchone())\n"
            "print('bench' in sys.modules)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=60, check=True, cwd=tmp_path)
    assert r.stdout.split("\n")[:4] == ["(6, 2)", "[('EMA-0000', 3), ('EMA-0001', 3)]",
                                        "(1,)", "False"]


def test_a_trace_table_takes_the_given_actuator_and_its_file_time(fleet, tmp_path, capsys):
    from bench.bus.logs import load_trace
    table = tmp_path / "rig" / "run.npz"
    table.parent.mkdir()
    load_trace(sorted(fleet.rglob("*.log"))[0]).save(table)
    os.utime(table, (1.78e9, 1.78e9))
    db = str(tmp_path / "f.duckdb")
    assert main(["fleet", "ingest", str(table), "--db", db, "--actuator", "SN-42",
                 "--workers", "1"]) == 0
    assert "1 runs stored" in capsys.readouterr().out
    import duckdb
    con = duckdb.connect(db, read_only=True)
    row = con.execute("SELECT actuator_id, epoch(run_time), verdict FROM runs").fetchall()
    con.close()
    assert row == [("SN-42", 1.78e9, "HEALTHY")]


def test_bad_input_is_one_line(tmp_path, capsys):
    assert main(["fleet", "ingest", str(tmp_path / "nope"), "--db",
                 str(tmp_path / "f.duckdb")]) == 2
    assert capsys.readouterr().err.strip().startswith("error: no such file")
    assert main(["fleet", "status", "--db", str(tmp_path / "none.duckdb")]) == 2
    assert "no fleet store" in capsys.readouterr().err


def test_ingest_killed_mid_way_resumes_without_loss_or_duplicates(fleet, tmp_path):
    logs = tmp_path / "logs"
    shutil.copytree(fleet, logs)
    for p in sorted(logs.rglob("*.log")):       # 12 distinct logs: 6 copies, one frame more
        text = p.read_text()
        last = float(text.rstrip().rsplit("\n", 1)[-1].split(")")[0][1:])
        p.with_name(p.stem + "-b.log").write_text(text + f"({last + 1:.6f}) can0 7FF#00 R\n")
    db = tmp_path / "f.duckdb"
    env = dict(os.environ, PYTHONPATH=str(ROOT), BENCH_FLEET_BATCH="1")
    proc = subprocess.Popen([sys.executable, "-m", "bench", "fleet", "ingest", str(logs),
                             "--db", str(db), "--workers", "1"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    assert proc.stderr is not None
    os.set_blocking(proc.stderr.fileno(), False)
    seen, buf, deadline = 0, b"", time.monotonic() + 120
    while seen < 3 and time.monotonic() < deadline and proc.poll() is None:
        buf += proc.stderr.read() or b""
        done = re.findall(rb"(\d+)/12", buf)
        seen = int(done[-1]) if done else 0
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)            # by PID, mid-ingest
    assert proc.wait(timeout=30) == -signal.SIGKILL
    proc.stderr.close()
    assert 3 <= seen < 12
    from bench.fleet.ingest import ingest
    res = ingest([str(logs)], db, workers=1, progress=False)
    assert res.files == 12 and res.skipped >= 3 and res.skipped + res.stored == 12
    import duckdb
    con = duckdb.connect(str(db), read_only=True)
    assert con.execute("SELECT count(*), count(DISTINCT digest) FROM runs").fetchone() \
        == (12, 12)
    con.close()
