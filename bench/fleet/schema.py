"""The fleet store's schema and its migrations (DuckDB).

The schema is versioned: the `meta` table holds ``schema_version``; `MIGRATIONS` are
ordered functions, migration k takes a store from version k to k + 1, each in one
transaction with the version bump, so a store is always at a version it claims.
`migrate` brings any older store up to `SCHEMA_VERSION` and refuses a newer one (a
store written by a later bench).

Tables (docs/fleet.md has every column with its unit):

- ``runs``: one row per ingested log, primary key ``digest`` (sha256 of the file's
  bytes), with ``actuator_id`` and ``run_time`` (UTC, indexed together): health indexes,
  verdict and the usage columns (version 2; NULL until the usage computation lands);
- ``failures``: logs that could not be ingested, with their one-line error;
- ``meta``: ``schema_version`` and when the store was created.

A damaged store is one line naming it and what to do (`DAMAGED`): a file DuckDB cannot
read (cut short, overwritten), a schema version that is no version this bench knows (not
a number, below 0), or tables that are not those of the version it claims (`check_tables`
against the tables the migrations make, built in memory).
"""

from __future__ import annotations

import datetime as dt
import functools
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from bench import BenchError

INDEX_COLUMNS = ("cp", "ci", "ci_harmonic", "peak_ratio", "mean_error_m", "lost_motion_m",
                 "harmonic_distortion", "friction_current_a")
USAGE_COLUMNS = {
    "travel_m": "DOUBLE",           # nut travel, sum |dx| (m)
    "screw_revs": "DOUBLE",         # screw revolutions
    "reversals": "BIGINT",          # direction reversals
    "equivalent_load_n": "DOUBLE",  # cubic-mean equivalent axial load (N)
    "life_consumed": "DOUBLE",      # fraction of the L10 life used by this run
    "i2t_a2s": "DOUBLE",            # integral of current squared (A^2 s)
    "time_hot_s": "DOUBLE",         # time with the winding above its hot limit (s)
}


def _v1(con: Any) -> None:
    """Version 1: meta, runs (indexes and verdict), failures."""
    con.execute("CREATE TABLE IF NOT EXISTS meta (key VARCHAR PRIMARY KEY, value VARCHAR)")
    idx = ", ".join(f"{c} DOUBLE" for c in INDEX_COLUMNS)
    con.execute(
        "CREATE TABLE runs (digest VARCHAR PRIMARY KEY, actuator_id VARCHAR NOT NULL, "
        "run_time TIMESTAMP NOT NULL, path VARCHAR, bytes BIGINT, "
        "ingested_at TIMESTAMP, rows BIGINT, "
        "duration_s DOUBLE, mode INTEGER, f0_hz DOUBLE, verdict VARCHAR, level INTEGER, "
        f"reasons VARCHAR, notes VARCHAR, {idx})")
    con.execute("CREATE INDEX runs_actuator_time ON runs (actuator_id, run_time)")
    con.execute(
        "CREATE TABLE failures (digest VARCHAR PRIMARY KEY, path VARCHAR, "
        "actuator_id VARCHAR, error VARCHAR, ingested_at TIMESTAMP)")
    con.execute("INSERT OR REPLACE INTO meta VALUES ('created_at', ?)",
                [_utc_now().isoformat(timespec="seconds")])


def _utc_now() -> dt.datetime:
    """Now, UTC, without a zone (the store's times are all UTC)."""
    return dt.datetime.now(dt.UTC).replace(tzinfo=None)


def _v2(con: Any) -> None:
    """Version 2: the usage columns on `runs` (NULL for the runs stored before)."""
    for name, kind in USAGE_COLUMNS.items():
        con.execute(f"ALTER TABLE runs ADD COLUMN {name} {kind}")


MIGRATIONS: list[Callable[[Any], None]] = [_v1, _v2]
"""MIGRATIONS[k] takes a store from version k to k + 1 (0: an empty file)."""
SCHEMA_VERSION = len(MIGRATIONS)


DAMAGED = ("restore the store from a copy, or make a new one from the logs (`bench fleet "
           "ingest LOGS --db NEW.duckdb`)")
"""What to do with a damaged store."""


@contextmanager
def damage(path: str | Path) -> Iterator[None]:
    """DuckDB's errors while the store at `path` is read or written, as one BenchError
    naming the store and what to do (a file cut short gave `IOException`)."""
    import duckdb
    kinds = (duckdb.IOException, duckdb.CatalogException, duckdb.SerializationException,
             duckdb.InternalException, duckdb.FatalException, duckdb.InvalidInputException)
    try:
        yield
    except kinds as exc:           # not a constraint of a write: that is the caller's
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise BenchError(f"{path}: the fleet store is damaged or unreadable ({first}); "
                         f"{DAMAGED}") from None


def version(con: Any) -> int:
    """The store's schema version (0 for an empty database); BenchError for one that is
    no version (not a whole number, or below 0)."""
    has = con.execute("SELECT count(*) FROM information_schema.tables "
                      "WHERE table_name = 'meta'").fetchone()[0]
    if not has:
        return 0
    row = con.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
    try:
        v = int(row[0]) if row else 0
    except (TypeError, ValueError):
        raise BenchError(f"not a fleet store: its schema_version is {row[0]!r}, not a "
                         "number") from None
    if v < 0 or (row and str(row[0]).strip() != str(v)):
        raise BenchError(f"its schema_version {row[0]!r} is no version a bench writes (0 "
                         f"to {SCHEMA_VERSION}): the store is damaged or edited; {DAMAGED}")
    return v


@functools.cache
def expected_tables(target: int) -> dict[str, tuple[str, ...]]:
    """Table -> its column names, as the migrations up to `target` make them (built in
    an in-memory DuckDB)."""
    import duckdb
    con = duckdb.connect(":memory:")
    try:
        for k in range(target):
            MIGRATIONS[k](con)
        return _tables(con)
    finally:
        con.close()


def _tables(con: Any) -> dict[str, tuple[str, ...]]:
    rows = con.execute("SELECT table_name, column_name FROM information_schema.columns "
                       "ORDER BY table_name, ordinal_position").fetchall()
    out: dict[str, list[str]] = {}
    for t, c in rows:
        out.setdefault(t, []).append(c)
    return {t: tuple(c) for t, c in out.items()}


def check_tables(con: Any, have: int) -> None:
    """BenchError when the store's tables are not those of the version `have` it claims
    (a store claiming version 1 with version 2's columns: its migration failed on
    "Column with name travel_m already exists")."""
    if have == 0:
        return
    want, got = expected_tables(have), _tables(con)
    for table, cols in want.items():
        if got.get(table) != cols:
            extra = sorted(set(got.get(table, ())) - set(cols))
            lack = sorted(set(cols) - set(got.get(table, ())))
            why = "; ".join(x for x in (
                f"no table {table}" if table not in got else "",
                f"{table} has {', '.join(extra)} that version {have} has not" if extra
                and table in got else "",
                f"{table} lacks {', '.join(lack)}" if lack and table in got else "") if x)
            raise BenchError(f"it claims schema version {have} but its tables are not that "
                             f"version's ({why or 'columns in another order'}): the store is "
                             f"damaged or edited; {DAMAGED}")


def _refuse_foreign(con: Any, have: int) -> None:
    """BenchError for a database of other tables (no schema version, yet tables): not a
    fleet store, and not to be written into."""
    if have:
        return
    tables = [r[0] for r in con.execute("SELECT table_name FROM information_schema.tables"
                                        ).fetchall()]
    if tables:
        raise BenchError(f"not a fleet store: a database with table(s) "
                         f"{', '.join(sorted(tables))} and no schema version (a fleet store "
                         "is made in a new file)")


def migrate(con: Any, target: int = SCHEMA_VERSION) -> int:
    """Apply the migrations from the store's version up to `target`, each with its
    version bump in one transaction; returns the version reached."""
    have = version(con)
    if have > SCHEMA_VERSION:
        raise BenchError(f"the fleet store has schema version {have}, newer than this "
                         f"bench's {SCHEMA_VERSION}: update the bench")
    _refuse_foreign(con, have)
    check_tables(con, have)
    for k in range(have, target):
        con.execute("BEGIN TRANSACTION")
        try:
            MIGRATIONS[k](con)
            con.execute("INSERT OR REPLACE INTO meta VALUES ('schema_version', ?)",
                        [str(k + 1)])
            con.execute("COMMIT")
        except Exception:
            con.execute("ROLLBACK")
            raise
    return max(have, target)


def _check_magic(p: Path) -> None:
    """BenchError when `p` is a file but not a DuckDB database (its header has "DUCK" at
    byte 8): DuckDB's own messages for a Parquet or CSV file given as the store do not
    say so ("Cannot launch in-memory database in read-only mode"); nor an empty file or a
    folder in its place (DuckDB's "IO Error")."""
    if p.is_dir():
        raise BenchError(f"{p}: a folder, not a fleet store (give the store's file, e.g. "
                         "fleet.duckdb)")
    if not p.is_file():
        return
    if p.stat().st_size == 0:
        raise BenchError(f"{p}: an empty file, not a fleet store (remove it, or give "
                         "another --db)")
    try:
        with p.open("rb") as fh:
            head = fh.read(12)
    except OSError as exc:
        raise BenchError(f"{p}: cannot read the fleet store ({exc.strerror})") from None
    if head[8:12] != b"DUCK":
        raise BenchError(f"{p}: not a fleet store (not a DuckDB database file; a fleet store "
                         "is the file `bench fleet ingest --db` makes)")


def connect(path: str | Path, read_only: bool = False, target: int = SCHEMA_VERSION
            ) -> Any:
    """A DuckDB connection to the store at `path`, migrated to `target` (read-only: not
    migrated, and BenchError when it does not exist or is older than this bench)."""
    import duckdb
    p = Path(path)
    if read_only and not p.exists():
        raise BenchError(f"no fleet store at {p} (make one with `bench fleet ingest`)")
    if not read_only and p.parent and not p.parent.exists():
        raise BenchError(f"{p.parent}: no such directory for the fleet store")
    _check_magic(p)
    try:
        con = duckdb.connect(str(p), read_only=read_only)
    except duckdb.Error as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        held = re.search(r"Conflicting lock is held in .*\(PID (\d+)\)", first)
        if "Could not set lock" in first and held:
            raise BenchError(f"{p}: the fleet store is in use by another process (PID "
                             f"{held.group(1)}; DuckDB lets one process open it to write): "
                             "wait for that one to end, or give another --db") from None
        raise BenchError(f"{p}: cannot open the fleet store: "
                         f"{first.removeprefix('IO Error: ')}") from None
    try:
        with damage(p):
            _ready(con, p, read_only, target)
    except BaseException:
        con.close()
        raise
    return con


def _ready(con: Any, p: Path, read_only: bool, target: int) -> None:
    """`connect`'s checks (read-only: the current version, its tables) or migration."""
    if read_only:
        try:
            have = version(con)
            _refuse_foreign(con, have)
            if have <= SCHEMA_VERSION:
                check_tables(con, have)
        except BenchError as exc:
            raise BenchError(f"{p}: {exc}") from None
        if have != SCHEMA_VERSION:
            raise BenchError(f"{p}: fleet store schema version {have}, this bench reads "
                             f"{SCHEMA_VERSION} ("
                             + ("update the bench)" if have > SCHEMA_VERSION else
                                "run `bench fleet ingest` on it to migrate)"))
        return
    try:
        migrate(con, target)
    except BenchError as exc:
        raise BenchError(f"{p}: {exc}") from None
