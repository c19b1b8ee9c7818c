"""The fleet store on tiny hand-made stores: schema versions and migration, idempotent
writes, export, the status (trend, RUL over days), the ingest's path and id rules."""

from __future__ import annotations

import datetime as dt
import math

import duckdb
import numpy as np
import pytest

from bench import BenchError
from bench.fleet import ingest as G
from bench.fleet import schema as S
from bench.fleet import status as T
from bench.fleet.store import Store

T0 = dt.datetime(2026, 1, 5, 8, 0)


def run_row(k: int, actuator: str = "A1", ci: float = 1.0, verdict: str = "HEALTHY",
            **extra: object) -> dict[str, object]:
    return {"digest": f"d{actuator}{k:05d}", "actuator_id": actuator,
            "run_time": T0 + dt.timedelta(days=k), "path": f"/logs/{actuator}/{k}.log",
            "bytes": 100, "rows": 2000, "duration_s": 2.0, "mode": 1, "f0_hz": 2.0,
            "verdict": verdict, "level": 0, "reasons": "r", "notes": "", "ci": ci,
            "ci_harmonic": ci, "cp": 1.0, **extra}


def test_new_store_is_at_the_current_version(tmp_path):
    with Store(tmp_path / "f.duckdb") as st:
        assert S.version(st.con) == S.SCHEMA_VERSION == 2
        cols = {r[0] for r in st.con.execute("DESCRIBE runs").fetchall()}
    assert set(S.USAGE_COLUMNS) <= cols and {"digest", "actuator_id", "run_time"} <= cols


def test_v1_store_migrates_and_keeps_its_data(tmp_path):
    path = tmp_path / "v1.duckdb"
    con = S.connect(path, target=1)
    assert S.version(con) == 1
    con.execute("INSERT INTO runs (digest, actuator_id, run_time, ci, verdict) VALUES "
                "('abc', 'A7', TIMESTAMP '2026-01-05 08:00:00', 0.91, 'DEGRADED')")
    con.execute("INSERT INTO failures (digest, path, error) VALUES ('bad', '/x.log', 'e')")
    assert "travel_m" not in {r[0] for r in con.execute("DESCRIBE runs").fetchall()}
    con.close()
    with Store(path) as st:                    # opening for writing migrates
        assert S.version(st.con) == 2
        row = st.con.execute("SELECT actuator_id, ci, verdict, travel_m, life_consumed "
                             "FROM runs").fetchall()
        assert row == [("A7", 0.91, "DEGRADED", None, None)]
        assert st.known() == {"abc", "bad"}


def test_a_newer_store_is_refused(tmp_path):
    path = tmp_path / "new.duckdb"
    Store(path).close()
    con = duckdb.connect(str(path))
    con.execute("UPDATE meta SET value = '99' WHERE key = 'schema_version'")
    con.close()
    with pytest.raises(BenchError, match="newer"):
        Store(path)


def test_an_empty_file_or_a_folder_as_the_store_is_named_so(tmp_path):
    """An empty file or a folder given as --db was DuckDB's "IO Error: The file ... exists,
    but it is not a valid DuckDB database file!" (or "Is a directory"): said in words,
    for reading and for writing, and the empty file is left as it was."""
    empty, folder = tmp_path / "e.duckdb", tmp_path / "d.duckdb"
    empty.touch()
    folder.mkdir()
    for read_only in (False, True):
        with pytest.raises(BenchError, match=f"^{empty}: an empty file, not a fleet store"):
            Store(empty, read_only=read_only)
        with pytest.raises(BenchError, match=f"^{folder}: a folder, not a fleet store"):
            Store(folder, read_only=read_only)
    assert empty.stat().st_size == 0 and not any(folder.iterdir())


def test_a_file_that_is_not_a_duckdb_database_is_named_so(tmp_path):
    """`bench fleet status --db x.parquet` said "cannot open the fleet store: Catalog
    Error: Cannot launch in-memory database in read-only mode!"."""
    pq = tmp_path / "x.parquet"
    pq.write_bytes(b"PAR1" + bytes(40) + b"PAR1")
    junk = tmp_path / "r.duckdb"
    junk.write_bytes(bytes(range(100)))
    for path in (pq, junk):
        for read_only in (False, True):
            with pytest.raises(BenchError, match=f"^{path}: not a fleet store \\(not a "
                                                 "DuckDB database file"):
                Store(path, read_only=read_only)


def test_a_database_that_is_not_a_fleet_store_is_one_line(tmp_path):
    """Found by fuzzing: a DuckDB file of other tables given to `bench fleet
    ingest` got the fleet's tables added to it, or failed with "CatalogException: Table
    with name "runs" already exists!" (exit 1); a schema_version that is not a number
    was a ValueError (exit 1) in every fleet command; `status` on a newer store said to
    migrate it with `ingest`, which refuses it."""
    other, runs, bad = (tmp_path / n for n in ("other.duckdb", "runs.duckdb", "bad.duckdb"))
    con = duckdb.connect(str(other))
    con.execute("CREATE TABLE x (a INTEGER)")
    con.close()
    con = duckdb.connect(str(runs))
    con.execute("CREATE TABLE runs (a INTEGER)")
    con.close()
    for path, tables in ((other, "x"), (runs, "runs")):
        for read_only in (False, True):     # status said "run `bench fleet ingest` on it"
            with pytest.raises(BenchError, match=f"^{path}: not a fleet store: a database "
                                                 f"with table\\(s\\) {tables} and no schema"):
                Store(path, read_only=read_only)
    assert {r[0] for r in duckdb.connect(str(other)).execute(
        "SELECT table_name FROM information_schema.tables").fetchall()} == {"x"}
    Store(bad).close()
    con = duckdb.connect(str(bad))
    con.execute("UPDATE meta SET value = 'x' WHERE key = 'schema_version'")
    con.close()
    for read_only in (False, True):
        with pytest.raises(BenchError, match=f"^{bad}: not a fleet store: its schema_version "
                                             "is 'x', not a number"):
            Store(bad, read_only=read_only)
    con = duckdb.connect(str(bad))
    con.execute("UPDATE meta SET value = '9' WHERE key = 'schema_version'")
    con.close()
    with pytest.raises(BenchError, match=r"schema version 9, this bench reads 2 \(update "):
        Store(bad, read_only=True)


def test_read_only_needs_an_existing_current_store(tmp_path):
    with pytest.raises(BenchError, match="no fleet store"):
        Store(tmp_path / "none.duckdb", read_only=True)
    S.connect(tmp_path / "old.duckdb", target=1).close()
    with pytest.raises(BenchError, match="schema version 1"):
        Store(tmp_path / "old.duckdb", read_only=True)


def test_the_same_digest_is_stored_once(tmp_path):
    with Store(tmp_path / "f.duckdb") as st:
        assert st.write([run_row(0), run_row(1)]) == 2
        assert st.write([run_row(1), run_row(2)]) == 1
        assert st.write([{"digest": "dA100002", "path": "p", "error": "x"}]) == 1
        assert st.con.execute("SELECT count(*), count(DISTINCT digest) FROM runs"
                              ).fetchone() == (3, 3)


def test_a_failing_batch_leaves_nothing(tmp_path):
    with Store(tmp_path / "f.duckdb") as st:
        bad = run_row(1)
        bad["run_time"] = None                 # NOT NULL
        with pytest.raises(duckdb.Error):
            st.write([run_row(0), bad])
        assert st.count() == 0


def test_export_is_plain_parquet(tmp_path):
    with Store(tmp_path / "f.duckdb") as st:
        st.write([run_row(k) for k in range(3)])
        paths = st.export(tmp_path / "out")
    assert sorted(p.name for p in paths) == ["failures.parquet", "meta.parquet",
                                              "runs.parquet"]
    con = duckdb.connect()
    n, a = con.execute(f"SELECT count(*), min(actuator_id) FROM "
                       f"'{tmp_path / 'out' / 'runs.parquet'}'").fetchone()
    assert (n, a) == (3, "A1")


def test_status_trend_and_rul_over_days(tmp_path):
    days = np.arange(40)
    ci = np.where(days < 20, 1.0, 1.0 - 0.02 * (days - 20))   # 0.93 at day 23.5
    with Store(tmp_path / "f.duckdb") as st:
        st.write([run_row(int(k), "A1", float(c)) for k, c in zip(days[:32], ci[:32], strict=True)])
        st.write([run_row(int(k), "B2", 1.0) for k in days[:5]])
        rows = T.fleet_status(st)
    a, b = rows
    assert (a.ident, a.tests, b.ident, b.tests) == ("A1", 32, "B2", 5)
    assert a.slope_per_day == pytest.approx(-0.02, rel=1e-6)
    assert math.isfinite(a.rul_days) and a.rul_days > 0     # warning crossed on day 31
    lo, hi = a.rul_band_days
    assert lo <= a.rul_days <= hi
    # the line reaches 0.56 on day 42: 11 days after the last test
    assert a.rul_days == pytest.approx(11.0, abs=1.0)
    assert not math.isfinite(b.rul_days) and "above the threshold" in b.rul_why
    assert b.slope_per_day == pytest.approx(0.0, abs=1e-12)
    text = T.format_table(rows)
    assert "A1" in text.splitlines()[1] and "n/a (no run with a load signal)" in text


def test_usage_columns_of_a_constant_load_run():
    """2 rev/s for 5 s under 5 kN, winding 410 K for the second half: the store's usage
    columns by hand (L10 = (22 kN / 5 kN)^3 10^6 rev, docs/usage.md)."""

    from bench.signals.trace import Trace
    from plant_rt.params import PlantParams
    p = PlantParams()
    n, dt = 5001, 1e-3
    rev = np.arange(n) * 0.002
    temp = np.where(np.arange(n) < 2500, 300.0, 410.0)
    tr = Trace({"t_s": np.arange(n) * dt,
                "motor_angle_rad": rev * 2 * math.pi / p.reducer.ratio,
                "load_force_n": np.full(n, 5000.0), "current_a": np.full(n, 2.0),
                "winding_temperature_k": temp}, {"period_s": dt})
    u = G.usage_columns(tr)
    assert set(u) == set(S.USAGE_COLUMNS)
    assert u["screw_revs"] == pytest.approx(10.0, abs=1e-3)
    assert u["travel_m"] == pytest.approx(10.0 * p.screw.lead_m, rel=1e-3)
    assert u["equivalent_load_n"] == pytest.approx(5000.0, rel=1e-9)
    assert u["life_consumed"] == pytest.approx(u["screw_revs"] / (4.4 ** 3 * 1e6), rel=1e-9)
    assert u["reversals"] == 0
    assert u["i2t_a2s"] == pytest.approx(4.0 * 5.0, rel=1e-2)
    assert u["time_hot_s"] == pytest.approx(2.5, abs=0.01)


def test_expand_files_dirs_globs_and_missing(tmp_path):
    (tmp_path / "a" / "b").mkdir(parents=True)
    for p in ("a/x.log", "a/b/y.log", "a/b/z.npz", "a/b/notes.txt"):
        (tmp_path / p).write_text("x")
    got = G.expand([str(tmp_path / "a")])
    assert [p.name for p in got] == ["y.log", "z.npz", "x.log"]
    assert [p.name for p in G.expand([str(tmp_path / "**" / "*.log")])] == ["y.log", "x.log"]
    with pytest.raises(BenchError, match="no such file"):
        G.expand([str(tmp_path / "nope")])
    # an empty directory was "0 files ... 0 runs stored", exit 0, and made the store
    # (found by fuzzing)
    (tmp_path / "empty").mkdir()
    with pytest.raises(BenchError, match="empty: a directory with no log in it"):
        G.expand([str(tmp_path / "empty")])


def test_actuator_id_rule(tmp_path):
    from bench.signals.trace import Trace
    f = tmp_path / "EMA-7" / "run.log"
    tr = Trace({"t_s": np.zeros(2)})
    assert G.actuator_id(tr, f, None) == "EMA-7"
    assert G.actuator_id(tr, f, "X1") == "X1"
    tr.meta["serial_number"] = 123456
    assert G.actuator_id(tr, f, "X1") == "123456"


def test_ingest_passes_workers_and_scheduler_to_the_pool(tmp_path, monkeypatch):
    import bench.runtime.workers
    seen = {}

    def fake_run_all(fn, jobs, workers=None, progress=True, **kw):
        seen.update(workers=workers, jobs=list(jobs), **kw)
        return []
    monkeypatch.setattr(bench.runtime.workers, "run_all", fake_run_all)
    (tmp_path / "A3").mkdir()
    (tmp_path / "A3" / "x.log").write_text("(1.0) can0 080#01\n")
    res = G.ingest([str(tmp_path / "A3")], tmp_path / "f.duckdb", workers=3,
                   scheduler="tcp://127.0.0.1:1", progress=False)
    assert seen["workers"] == 3 and seen["scheduler"] == "tcp://127.0.0.1:1"
    assert [j[2] for j in seen["jobs"]] == [None] and res.files == 1


def test_usage_columns_of_a_run_without_motor_angle_are_null():
    """A run without encoder angle, current or temperature: its travel, revolutions,
    reversals, life, I2t and time hot are NULL (not 0; reversals were int(NaN))."""
    from bench.signals.trace import Trace
    n = 200
    tr = Trace({"t_s": np.arange(n) * 1e-3, "position_m": np.linspace(0, 0.01, n),
                "load_force_n": np.full(n, 100.0)}, {"period_s": 1e-3})
    u = G.usage_columns(tr)
    assert {k for k, v in u.items() if v is None} == {
        "travel_m", "screw_revs", "reversals", "equivalent_load_n", "life_consumed",
        "i2t_a2s", "time_hot_s"}


def _stored(path) -> None:
    with Store(path) as st:
        st.write([run_row(k) for k in range(3)])


@pytest.mark.parametrize("damage", ["cut", "v1-with-v2-columns", "version -5", "version 1.5"])
def test_a_damaged_store_is_one_line_naming_it_and_what_to_do(tmp_path, damage):
    """A store cut in half gave IOException, one claiming schema 1 with schema-2 columns
    CatalogException, schema version "-5" IndexError."""
    path = tmp_path / "f.duckdb"
    _stored(path)
    if damage == "cut":
        data = path.read_bytes()
        path.write_bytes(data[:len(data) // 2])
    else:
        value = {"v1-with-v2-columns": "1", "version -5": "-5", "version 1.5": "1.5"}[damage]
        con = duckdb.connect(str(path))
        con.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'", [value])
        con.close()
    for read_only in (True, False):
        with pytest.raises(BenchError) as err:
            with Store(path, read_only=read_only) as st:
                st.known()
        msg = str(err.value)
        assert msg.startswith(f"{path}: ") and "\n" not in msg
        assert "restore the store from a copy" in msg or "not a number" in msg, msg


def test_a_job_that_fails_in_a_worker_is_named_by_its_label():
    from bench.runtime.workers import _job_error, _JobFailed
    jobs = [("a.log",), ("b.log",), ("c.log",)]
    err = _job_error(_JobFailed(1, "ValueError: boom"), "fleet ingest", jobs,
                     lambda j: j[0], 0, 3)
    assert str(err) == "fleet ingest: b.log failed in a worker: ValueError: boom"
    err = _job_error(RuntimeError("worker died"), "fleet ingest", jobs, None, 2, 1)
    assert str(err) == "fleet ingest: job 2 failed in a worker: RuntimeError: worker died"


def test_levels_of_old_stores_read_in_the_one_encoding(tmp_path):
    """A version-1 store kept UNKNOWN as a NULL level (and a NULL verdict reads as none):
    the status reads every stored run's level as `bench.core.verdict.Level` (-1 for UNKNOWN);
    a verdict that is no level is one line naming it, not a traceback."""
    from bench.core.verdict import Level
    path = tmp_path / "v1.duckdb"
    con = S.connect(path, target=1)
    con.execute("INSERT INTO runs (digest, actuator_id, run_time, ci, ci_harmonic, verdict, "
                "level) VALUES ('a', 'A7', TIMESTAMP '2026-01-05 08:00:00', 0.91, 0.91, "
                "'DEGRADED', 1), ('b', 'A8', TIMESTAMP '2026-01-05 08:00:00', 1.0, 1.0, "
                "NULL, NULL), ('c', 'A9', TIMESTAMP '2026-01-05 08:00:00', 1.0, 1.0, "
                "'UNKNOWN', NULL)")
    con.close()
    with Store(path) as st:
        rows = {r.ident: r for r in T.fleet_status(st)}
    assert rows["A7"].level is Level.DEGRADED and rows["A7"].verdict == "DEGRADED"
    assert rows["A8"].level is Level.UNKNOWN and int(rows["A8"].level) == -1
    assert rows["A8"].verdict == rows["A9"].verdict == "UNKNOWN"
    with Store(path) as st:
        st.con.execute("UPDATE runs SET verdict = 'FLAGGED' WHERE digest = 'a'")
        with pytest.raises(BenchError, match="^the fleet store holds a run whose verdict is "
                                             "not a level: 'FLAGGED'$"):
            T.fleet_status(st)


def test_an_unjudged_run_is_stored_with_the_one_unknown_code(tmp_path):
    """The ingest stores UNKNOWN as its code -1 (`bench.core.verdict.Level`), not as NULL."""
    from bench.signals.trace import Trace
    t = np.arange(2000) * 1e-3
    cols = ("mode", "setpoint_position_m", "position_m", "current_a", "motor_speed_rad_s",
            "setpoint_speed_rad_s", "current_demand_a", "motor_angle_rad")
    tr = Trace({"t_s": t, **{c: np.zeros_like(t) for c in cols}}, {"source": "idle"})
    path = tmp_path / "idle.npz"
    tr.save(path)
    row = G._row(path, "d", None, tr)             # mode 0 throughout: nothing commanded
    assert (row["verdict"], row["level"]) == ("UNKNOWN", -1)


def test_a_store_another_process_holds_is_named_with_that_process(tmp_path):
    """A second ingest beside a running one printed DuckDB's 'Could not set lock on file
    ...: Conflicting lock is held in .../python3.11 (PID N). See also https://duckdb.org/
    ...': what to do was not said."""
    import subprocess
    import sys
    db = tmp_path / "f.duckdb"
    Store(db).close()
    holder = subprocess.Popen(
        [sys.executable, "-c", "import duckdb, sys, time; c = duckdb.connect(sys.argv[1]); "
         "print('held', flush=True); time.sleep(30)", str(db)],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        with pytest.raises(BenchError) as err:
            Store(db)
        msg = str(err.value)
        assert f"in use by another process (PID {holder.pid}" in msg, msg
        assert "wait for that one to end" in msg and "duckdb.org" not in msg, msg
    finally:
        holder.kill()
        holder.wait(10)
        if holder.stdout is not None:
            holder.stdout.close()
