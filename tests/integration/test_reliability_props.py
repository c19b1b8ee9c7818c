"""Property tests of every input path (hypothesis, derandomized, a few examples each):
candump and the other log formats, CSV and Parquet tables, npz metadata, JSON and TOML
inputs, and the commands' options. For each generated input, the command (in-process,
`bench.cli.main`) either exits 0 with a result that agrees with the input, or exits 2
with one line; nothing is written outside the output folder; no input's bytes change.

Each example runs in a sandbox of its own: ``in/`` holds the inputs, ``out/`` is the
output folder, the working directory is ``in/``'s parent; every file under the sandbox
is compared before and after."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
import tempfile
from pathlib import Path

import can
import numpy as np
import pytest
from cli_errors import stub_steps
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from log_frames import run, write_log

from bench.cli import main

PROPS = settings(derandomize=True, deadline=None, database=None, max_examples=12,
                 suppress_health_check=[HealthCheck.too_slow,
                                        HealthCheck.function_scoped_fixture])


@contextlib.contextmanager
def sandbox():
    """(in, out) folders of a fresh sandbox, the working directory its root."""
    with tempfile.TemporaryDirectory(prefix="bench-prop-") as root:
        r = Path(root)
        (r / "in").mkdir()
        (r / "out").mkdir()
        old = os.getcwd()
        os.chdir(r)
        try:
            yield r / "in", r / "out"
        finally:
            os.chdir(old)


def files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def call(argv: list[str], inp: Path, out: Path, capsys, ok: tuple[int, ...] = (0,),
         allowed: tuple[str, ...] = ()) -> tuple[int, str, str]:
    """Run `bench argv`; check the three properties common to every path (rc in `ok` or
    2 with one line; nothing written outside `out` and the paths `allowed`, outputs the
    command was given; inputs unchanged)."""
    root = inp.parent
    before = files(root)
    capsys.readouterr()
    try:
        rc = main(argv)
    except SystemExit as exc:            # argparse: a usage error
        rc = int(exc.code or 0)
    cap = capsys.readouterr()
    after = files(root)
    assert rc in (*ok, 2), (argv, rc, cap.err)
    if rc == 2:
        lines = cap.err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), (argv, cap.err)
        assert "Traceback" not in cap.err
    changed = {k for k in set(before) | set(after) if before.get(k) != after.get(k)}
    places = ["out", *(os.path.normpath(a) for a in allowed)]
    assert all(any(k == p or k.startswith(p + os.sep) for p in places) for k in changed), \
        (argv, sorted(changed))
    assert {k: v for k, v in after.items() if k.startswith("in" + os.sep)} == \
        {k: v for k, v in before.items() if k.startswith("in" + os.sep)}, argv
    return rc, cap.out, cap.err


# --- candump and the other log formats --------------------------------------------------------

line_edits = st.lists(st.tuples(
    st.sampled_from(["drop", "junk", "plain", "crlf", "far", "blank", "foreign", "bom"]),
    st.integers(0, 10_000), st.text(max_size=30)), max_size=6)


def _candump_text(n: int, edits: list) -> tuple[str, bool]:
    """A candump -L log of n periods with line edits; whether it is intact."""
    buf = io.StringIO()
    w = can.CanutilsLogWriter(buf)
    for m in run(n):
        w.on_message_received(m)
    lines = buf.getvalue().splitlines(keepends=True)
    w.stop()
    for op, i, text in edits:
        k = i % len(lines)
        if op == "drop":
            lines.pop(k)
        elif op == "junk":
            lines.insert(k, text.replace("\n", " ") + "\n")
        elif op == "plain":
            lines.insert(k, "  can0  190   [6]  7E 00 00 00 40 00\n")
        elif op == "crlf":
            lines[k] = lines[k].rstrip("\n") + "\r\n"
        elif op == "far" and lines[k].startswith("(") and ")" in lines[k]:
            ts, rest = lines[k].split(")", 1)
            lines[k] = f"({float(ts[1:]) + 1e12:.6f}){rest}"
        elif op == "blank":
            lines.insert(k, "\n")
        elif op == "foreign":
            lines.insert(k, f"({1000.0 + k * 1e-4:.6f}) can0 190#0237\n")
        elif op == "bom":
            lines[0] = "\ufeff" + lines[0]
    return "".join(lines), not edits


@PROPS
@given(st.integers(1, 40), line_edits)
def test_candump_decodes_to_its_rows_or_is_one_line(capsys, n, edits):
    text, intact = _candump_text(n, edits)
    with sandbox() as (inp, out):
        log = inp / "run.log"
        log.write_text(text, newline="")
        rc, printed, _ = call(["decode", str(log), "-o", str(out / "t.csv")], inp, out, capsys)
        if rc:
            return
        rows = list(csv.DictReader(io.StringIO((out / "t.csv").read_text())))
        assert f"{len(rows)} SYNC periods" in printed
        assert all(math.isnan(float(v)) or math.isfinite(float(v))
                   for r in rows for v in r.values())
        if intact:                           # the values the frames carry, row by row
            assert len(rows) == n
            for k, r in enumerate(rows):
                assert float(r["current_a"]) == pytest.approx(0.01 * k, abs=1e-4)
                assert float(r["position_m"]) == pytest.approx(1e-6 * k, abs=1e-8)


@PROPS
@given(st.integers(2, 30), st.sets(st.integers(0, 200), max_size=8))
def test_every_log_format_decodes_to_the_candump_table(capsys, n, dropped):
    msgs = [m for i, m in enumerate(run(n)) if i not in dropped]
    writers = {".log": can.CanutilsLogWriter, ".asc": can.ASCWriter, ".blf": can.BLFWriter,
               ".trc": can.TRCWriter}
    with sandbox() as (inp, out):
        tables = {}
        for suffix, writer in writers.items():
            path = inp / f"run{suffix}"
            with writer(str(path)) as w:
                for m in msgs:
                    m.channel = 0 if suffix != ".log" else "can0"
                    w.on_message_received(m)
            rc, _, err = call(["decode", str(path), "-o", str(out / f"{suffix[1:]}.csv")],
                              inp, out, capsys)
            tables[suffix] = rc if rc else (out / f"{suffix[1:]}.csv").read_text()
        assert len(set(map(type, tables.values()))) == 1, tables   # all decode or none
        if isinstance(tables[".log"], str):
            ref = list(csv.reader(io.StringIO(tables[".log"])))
            for suffix, text in tables.items():
                got = list(csv.reader(io.StringIO(text)))
                assert len(got) == len(ref), suffix
                cols = ref[0].index("current_a"), ref[0].index("position_m")
                for a, b in zip(ref[1:], got[1:], strict=True):
                    for c in cols:
                        assert a[c] == b[c] or (a[c] == "nan" == b[c]), (suffix, a, b)


# --- tables: CSV and Parquet ------------------------------------------------------------------

cells = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                  st.sampled_from(["", " ", "abc", "1e308", "-1e308", "1,5", "0x10"]),
                  st.integers(-10**6, 10**6).map(str))
headers = st.sampled_from([["time", "pos", "load"], ["\ufefftime", "pos", "load"],
                           ["time", "pos", "pos"], ["time", "pos"], ["time", " pos ", "load"],
                           ["ti\x00me", "pos", "load"]])
MAP = [{"signal": "t_s", "column": "time", "unit": "ms"},
       {"signal": "position_m", "column": "pos", "unit": "mm"},
       {"signal": "load_force_n", "column": "load", "unit": "kgf"}]


@PROPS
@given(headers, st.lists(st.tuples(st.integers(0, 10**6), cells, cells), max_size=12),
       st.sampled_from(["\n", "\r\n"]), st.booleans())
def test_a_csv_table_imports_to_its_own_values_or_is_one_line(capsys, header, rows, end,
                                                              blank):
    rows = sorted(rows)
    body = [",".join(header)] + [f"{t},{p},{f}" for t, p, f in rows]
    if blank:
        body.insert(len(body) // 2 + 1, "")
    with sandbox() as (inp, out):
        (inp / "t.csv").write_text(end.join(body) + end, newline="")
        (inp / "m.json").write_text(json.dumps(MAP))
        rc, _, _ = call(["import", str(inp / "t.csv"), "--map", str(inp / "m.json"), "-o",
                         str(out / "t.npz")], inp, out, capsys)
        if rc:
            return
        from bench.signals.trace import Trace
        tr = Trace.load(out / "t.npz")
        assert np.all(np.diff(tr.t) > 0) and not np.isinf(tr["position_m"]).any()
        given_pos = {float(p) * 1e-3 for _, p, _ in rows if p.strip() and _num(p)}
        assert all(math.isnan(v) or any(math.isclose(v, g, rel_tol=1e-12, abs_tol=1e-300)
                                        for g in given_pos) for v in tr["position_m"])


def _num(x: str) -> bool:
    try:
        return math.isfinite(float(x))
    except ValueError:
        return False


parquet_columns = st.sampled_from(["float", "int", "timestamp", "string", "bool", "null",
                                   "duration", "date"])


@PROPS
@given(parquet_columns, parquet_columns, st.integers(0, 8), st.booleans())
def test_a_parquet_table_imports_or_is_one_line(capsys, time_kind, pos_kind, n, dup):
    import datetime as dt

    import pyarrow as pa
    import pyarrow.parquet as pq

    def col(kind: str) -> pa.Array:
        k = np.arange(n)
        return {"float": pa.array(k * 0.5), "int": pa.array(k),
                "timestamp": pa.array(np.datetime64("2026-01-05", "ms") + k, pa.timestamp("ms")),
                "string": pa.array([f"x{i}" for i in k]), "bool": pa.array(k % 2 == 0),
                "null": pa.nulls(n), "duration": pa.array(k * 1000, pa.duration("us")),
                "date": pa.array([dt.date(2026, 1, 1 + int(i)) for i in k])}[kind]
    names = ["time", "pos", "pos" if dup else "load"]
    table = pa.Table.from_arrays([col(time_kind), col(pos_kind), col("float")], names=names)
    entries = [{**MAP[0], "unit": "s"}, *MAP[1:]]
    with sandbox() as (inp, out):
        pq.write_table(table, inp / "t.parquet")
        (inp / "m.json").write_text(json.dumps(entries))
        rc, _, _ = call(["import", str(inp / "t.parquet"), "--map", str(inp / "m.json"), "-o",
                         str(out / "t.csv")], inp, out, capsys)
        if rc == 0:
            from bench.signals.trace import Trace
            tr = Trace.load(out / "t.csv")
            assert time_kind in ("float", "int", "timestamp", "duration")
            assert np.all(np.diff(tr.t) > 0)


# --- npz metadata, JSON and TOML --------------------------------------------------------------

json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.floats(allow_nan=False), st.integers(),
              st.text(max_size=20), st.sampled_from(["x/../../y", "a\nb", "/abs", "." * 3])),
    lambda kids: st.one_of(st.lists(kids, max_size=3),
                           st.dictionaries(st.sampled_from(
                               ["actuator_serial", "actuator_id", "run_time", "source",
                                "period_s", "params", "signal", "column", "unit"]), kids,
                               max_size=4)), max_leaves=10)


@PROPS
@given(json_values)
def test_npz_metadata_of_any_shape_gives_a_usage_or_one_line(capsys, monkeypatch, meta):
    import bench.usage.figure as FIG
    monkeypatch.setattr(FIG, "save_usage_figure",
                        lambda s, title, path: path.write_bytes(b"png"))
    t = np.arange(200) * 1e-3
    x = 1e-3 * np.sin(2 * np.pi * 5 * t)
    with sandbox() as (inp, out):
        arrays = {"t_s": t, "position_m": x, "motor_angle_rad": x * 3000.0}
        np.savez(inp / "r.npz", __meta__=json.dumps(meta), **arrays)
        rc, printed, _ = call(["usage", str(inp / "r.npz"), "--plot", str(out / "p"),
                               "--json", str(out / "u.json")], inp, out, capsys)
        if rc == 0:
            doc = json.loads((out / "u.json").read_text())
            assert len(doc["runs"]) == 1 and len(os.listdir(out / "p")) == 2


@PROPS
@given(json_values)
def test_a_map_json_of_any_shape_imports_or_is_one_line(capsys, data):
    with sandbox() as (inp, out):
        (inp / "t.csv").write_text("time,pos,load\n0,1,2\n1,2,3\n2,3,4\n")
        (inp / "m.json").write_text(json.dumps(data))
        call(["import", str(inp / "t.csv"), "--map", str(inp / "m.json"), "-o",
              str(out / "t.npz")], inp, out, capsys)


@PROPS
@given(json_values)
def test_a_nominal_calibration_json_of_any_shape_is_taken_or_one_line(capsys, no_long_work,
                                                                      data):
    with sandbox() as (inp, out):
        write_log(str(inp / "run.log"), run(300))
        (inp / "n.json").write_text(json.dumps(data))
        call(["gap", str(inp / "run.log"), "--nominal", str(inp / "n.json"), "--json",
              str(out / "g.json"), "--workers", "1"], inp, out, capsys)


@settings(PROPS, max_examples=6)
@given(st.lists(line_edits, min_size=1, max_size=3))
def test_fleet_ingest_of_damaged_logs_stores_each_or_its_failure(capsys, edits):
    with sandbox() as (inp, out):
        for k, e in enumerate(edits):
            text, _ = _candump_text(30, e)
            (inp / "A1" / f"{k}.log").parent.mkdir(exist_ok=True)
            (inp / "A1" / f"{k}.log").write_text(text, newline="")
        rc, printed, _ = call(["fleet", "ingest", str(inp / "A1"), "--db",
                               str(out / "f.duckdb"), "--workers", "1"], inp, out, capsys)
        assert rc == 0
        import re
        m = re.search(r"(\d+) files: (\d+) already stored(?: \([^)]*\))?, (\d+) runs stored, "
                      r"(\d+) failed",
                      printed)
        files, skipped, stored, failed = map(int, m.groups())
        assert files == len(edits) and skipped + stored + failed == files


toml_text = st.one_of(
    st.text(max_size=80),
    st.builds(lambda k, v: f"{k} = {v}\n", st.sampled_from(
        ["name", "motor_kind", "load_sign", "lead_m", "stroke_m", "[sources]", "values"]),
        st.sampled_from(['"x"', "0", "-1", "1e400", "nan", "[1, 2]", "{a = 1}", '"bldc"'])))


@PROPS
@given(st.lists(toml_text, max_size=5))
def test_an_actuator_toml_of_any_text_is_read_or_one_line(capsys, parts):
    with sandbox() as (inp, out):
        (inp / "a.toml").write_text("".join(parts))
        rc, _, err = call(["calibrate", str(inp / "none.log"), "--actuator",
                           str(inp / "a.toml"), "-o", str(out / "c.json")], inp, out, capsys)
        assert rc == 2


# --- the commands' options ----------------------------------------------------------------------

hostile = st.one_of(st.sampled_from(["nan", "inf", "-inf", "-1", "0", "1e308", "", " ",
                                     "../../x", "/dev/null", "a\nb", "-", "x" * 300,
                                     "in/run.log", "in/t.csv", "in", "out", "out/x.json",
                                     "out/x.csv", "tcp://", "a=b", "usage.bogus=1"]),
                    st.text(st.characters(blacklist_categories=["Cs"]), max_size=12)
                    .filter(lambda t: not t.startswith("/")))
COMMANDS = {
    "decode": (["in/run.log"], ["-o", "--node-id", "--period", "--counts-per-rev",
                                "--format"]),
    "import": (["in/t.csv", "--map", "in/m.json", "-o", "out/t.npz"],
               ["-o", "--split-by", "--sync-period",
                                                    "--source-rate", "--format"]),
    "usage": (["in/run.log"], ["--json", "--plot", "--preload-n", "--load-rating-n",
                               "--set", "--preload"]),
    "calibrate": (["in/run.log", "-o", "out/c.json"], ["-o", "--holdout", "--nominal", "--actuator", "--params",
                                   "--controller"]),
    "gap": (["in/run.log"], ["--json", "--report", "--nominal", "--holdout-frac",
                             "--workers", "--scheduler", "--effects", "--fundamental"]),
    "fleet status": ([], ["--db", "--as-of", "--trend-tests", "--sort"]),
    "fleet export": (["--out", "out/x"], ["--db"]),
    "fleet synth": (["--actuators", "1", "--days", "1", "--out", "out/s"],
                    ["--seed", "--workers", "--scheduler", "--actuators", "--days", "--wear"]),
}


@pytest.fixture
def no_long_work(monkeypatch):
    """The long steps end the command at once (what is tested is what comes before)."""
    from bench import BenchError
    stub_steps(monkeypatch, (("bench.gap.calibrate", "calibrate"),
                             ("bench.gap.diagnose", "diagnose"),
                             ("bench.rig.rigcal", "calibrate_rig"),
                             ("bench.fleet.synth", "draw_fleet"),
                             ("bench.usage.figure", "save_usage_figure")),
               BenchError("reached the work"))


@settings(PROPS, max_examples=40)
@given(st.sampled_from(sorted(COMMANDS)), st.data())
def test_any_option_value_is_used_or_refused_in_one_line(capsys, no_long_work, command, data):
    from bench.cli.outputs import IO_TABLE
    base, options = COMMANDS[command]
    argv = [*command.split(), *base]
    outputs = {"-o": "output", **{f"--{k.replace('_', '-')}": k for k in
                                  (*IO_TABLE[command].files, *IO_TABLE[command].dirs)}}
    allowed = []
    for flag in data.draw(st.lists(st.sampled_from(options), max_size=3, unique=True)):
        value = data.draw(hostile)
        argv += [flag, value]
        if flag in outputs and outputs[flag] in (*IO_TABLE[command].files,
                                                  *IO_TABLE[command].dirs):
            allowed.append(value)
    with sandbox() as (inp, out):
        write_log(str(inp / "run.log"), run(20))
        (inp / "t.csv").write_text("time,pos\n0,1\n1,2\n2,3\n")
        (inp / "m.json").write_text(json.dumps(MAP[:2]))
        call(argv, inp, out, capsys, ok=(0, 3), allowed=tuple(a for a in allowed if a.strip()))
