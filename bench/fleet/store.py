"""The fleet store: a DuckDB file of runs (`bench.fleet.schema`), written in batches of
whole runs, each batch one transaction, and read back by actuator.

Idempotence: a run's key is its log digest (sha256 of the file's bytes); `known`
gives the digests already stored (runs and failures) so an ingest skips them, and the
insert is ``INSERT OR IGNORE`` so a digest is never stored twice even when two ingests
race. A killed ingest loses only its uncommitted batch, which the next ingest redoes.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from bench import BenchError
from bench.fleet import schema as S

RUN_COLUMNS = ("digest", "actuator_id", "run_time", "path", "bytes", "ingested_at", "rows",
               "duration_s",
               "mode", "f0_hz", "verdict", "level", "reasons", "notes",
               *S.INDEX_COLUMNS, *S.USAGE_COLUMNS)
FAILURE_COLUMNS = ("digest", "path", "actuator_id", "error", "ingested_at")
TABLES = ("runs", "failures", "meta")


def default_db() -> Path:
    """The store used without --db: $BENCH_FLEET_DB, else fleet.duckdb here."""
    return Path(os.environ.get("BENCH_FLEET_DB") or "fleet.duckdb")


def _guarded(method: Any) -> Any:
    """A Store method whose DuckDB errors are the one-line damaged-store BenchError."""
    import functools

    @functools.wraps(method)
    def call(self: Store, *args: Any, **kwargs: Any) -> Any:
        with S.damage(self.path):
            return method(self, *args, **kwargs)
    return call


class Store:
    """A fleet store open for writing (migrated to the current schema) or reading; a
    DuckDB error of any read or write is one line naming the store (`schema.damage`)."""

    def __init__(self, path: str | Path, read_only: bool = False) -> None:
        self.path = Path(path)
        self.con = S.connect(self.path, read_only=read_only)

    def close(self) -> None:
        self.con.close()

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -- writing ----------------------------------------------------------------------
    @_guarded
    def known(self) -> set[str]:
        """Digests already stored, as runs or as failures."""
        rows = self.con.execute("SELECT digest FROM runs UNION ALL "
                                "SELECT digest FROM failures").fetchall()
        return {r[0] for r in rows}

    @_guarded
    def failed(self) -> set[str]:
        """Digests stored as failures (skipped by an ingest until their row is deleted)."""
        return {r[0] for r in self.con.execute("SELECT digest FROM failures").fetchall()}

    @_guarded
    def write(self, results: list[dict[str, Any]]) -> int:
        """Store a batch of ingest results (runs and failures) in one transaction;
        returns how many were new."""
        runs = [r for r in results if "error" not in r]
        fails = [r for r in results if "error" in r]
        now = S._utc_now()
        for r in results:
            r.setdefault("ingested_at", now)
        before = self.count()
        self.con.execute("BEGIN TRANSACTION")
        try:
            if runs:
                self._insert("runs", RUN_COLUMNS, runs)
            if fails:
                self._insert("failures", FAILURE_COLUMNS, fails)
            self.con.execute("COMMIT")
        except Exception:
            self.con.execute("ROLLBACK")
            raise
        return self.count() - before

    def _insert(self, table: str, columns: tuple[str, ...], rows: list[dict[str, Any]]
                ) -> None:
        marks = ", ".join("?" for _ in columns)
        self.con.executemany(
            f"INSERT OR IGNORE INTO {table} ({', '.join(columns)}) VALUES ({marks})",
            [[r.get(c) for c in columns] for r in rows])

    @_guarded
    def count(self) -> int:
        """Runs and failures stored."""
        return int(self.con.execute("SELECT (SELECT count(*) FROM runs) + "
                                    "(SELECT count(*) FROM failures)").fetchone()[0])

    # -- reading ----------------------------------------------------------------------
    @_guarded
    def actuators(self) -> list[str]:
        return [r[0] for r in self.con.execute(
            "SELECT DISTINCT actuator_id FROM runs ORDER BY actuator_id").fetchall()]

    @_guarded
    def series(self, columns: tuple[str, ...], actuator: str | None = None
               ) -> dict[str, Any]:
        """Columns of the runs (all actuators, or one), ordered by actuator and time, as
        numpy arrays (run_time as epoch seconds)."""
        sel = ", ".join("epoch(run_time) AS run_time" if c == "run_time" else c
                        for c in ("actuator_id", "run_time", *columns))
        where = " WHERE actuator_id = ?" if actuator is not None else ""
        rel = self.con.execute(f"SELECT {sel} FROM runs{where} ORDER BY actuator_id, "
                               "run_time", [actuator] if actuator is not None else [])
        return rel.fetchnumpy()

    @_guarded
    def failures(self) -> list[tuple[str, str, str]]:
        return [tuple(r) for r in self.con.execute(
            "SELECT actuator_id, path, error FROM failures ORDER BY path").fetchall()]

    @_guarded
    def export(self, out_dir: str | Path) -> list[Path]:
        """Every table as Parquet (``runs.parquet``, ``failures.parquet``,
        ``meta.parquet``) in `out_dir`."""
        out = Path(out_dir)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise BenchError(f"{out}: cannot create the export directory: {exc}") from None
        paths = []
        for t in TABLES:
            p = out / f"{t}.parquet"
            if p.exists() and os.path.samefile(p, self.path):
                raise BenchError(f"--out {out}: {p.name} would be written over the store "
                                 f"{self.path} itself: export into another folder")
        for t in TABLES:
            p = out / f"{t}.parquet"
            self.con.execute(f"COPY (SELECT * FROM {t}) TO '{_quote(p)}' (FORMAT parquet)")
            paths.append(p)
        return paths


def _quote(p: Path) -> str:
    return str(p).replace("'", "''")
