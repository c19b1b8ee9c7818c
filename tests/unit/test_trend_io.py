"""Reading a trends CSV (bench.hums.trend_io) and `bench hums prognose`'s refusals of bad
input, each one line with exit 2: an infinite value, two values of an index at one time
(once merged into one test without a word), times far out of range (once a crash deep in
the filter), an output that is an input (once overwritten), units that do not match."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench import BenchError
from bench.cli import main
from bench.hums.trend_io import read_table


def _write(path, text):
    path.write_text(text)
    return path


def test_dates_wide_form_and_unit_in_the_header(tmp_path):
    f = _write(tmp_path / "rig.csv", "\ufeffdate,rms current [A]\n2024-03-01,2.1\n"
               "2024-03-03,2.2\n2024-03-02,2.15\n2024-03-05,\n")
    tab = read_table(f)
    (tr,) = tab.trends
    assert (tr.actuator, tr.index, tr.unit) == ("rig", "rms current", "A")
    assert tr.t.tolist() == [0.0, 1.0, 2.0]               # days since the first, sorted
    assert tr.y.tolist() == [2.1, 2.15, 2.2]
    assert tr.date(2.0) == "2024-03-03"
    assert any("out of time order" in n for n in tab.notes)
    assert any("1 missing value" in n for n in tab.notes)


@pytest.mark.parametrize("name, text", [
    ("rig.tsv", "day\tcurrent [A]\n0\t2.1\n1\t2.2\n2\t2.15\n"),
    ("rig.csv", "Test date;current [A]\n0;2,1\n1;2,2\n2;2,15\n"),
    ("rig.txt", "day;current [A]\n0;2.1\n1;2.2\n2;2.15\n"),
])
def test_tab_and_semicolon_tables_with_a_decimal_comma(tmp_path, name, text):
    """Before: only the comma delimited a trends file, so a rig's tab-separated export
    or a spreadsheet's semicolon CSV with decimal commas was 'no time column' or 'no
    index column'."""
    (tr,) = read_table(_write(tmp_path / name, text)).trends
    assert (tr.actuator, tr.index, tr.unit) == ("rig", "current", "A")
    assert tr.t.tolist() == [0.0, 1.0, 2.0]
    assert tr.y.tolist() == [2.1, 2.2, 2.15]


def test_dates_of_a_stated_layout(tmp_path):
    """Before: a spreadsheet's day-first dates could only be refused (not ISO)."""
    f = _write(tmp_path / "rig.csv", "date,current [A]\n01/03/2024,2.1\n03/03/2024,2.2\n")
    with pytest.raises(BenchError, match=r"rig.csv:2: .*nor an ISO date.*--date-format"):
        read_table(f)
    (tr,) = read_table(f, date_format="%d/%m/%Y").trends
    assert tr.t.tolist() == [0.0, 2.0] and tr.date(2.0) == "2024-03-03"
    with pytest.raises(BenchError, match=r"rig.csv:2: time '01/03/2024' is not a date of "
                                         r"--date-format '%Y-%m-%d'"):
        read_table(f, date_format="%Y-%m-%d")


def test_a_comma_csv_keeps_commas_out_of_its_numbers(tmp_path):
    f = _write(tmp_path / "rig.csv", 'day,current\n0,"2,1"\n')
    with pytest.raises(BenchError, match=r"rig.csv:2: value '2,1' is not a number"):
        read_table(f)


def test_a_compressed_file_and_standard_input(tmp_path, monkeypatch, capsys):
    """Before: `--trends -` was 'no trends file -' and a .csv.xz was not UTF-8 text."""
    import io
    import lzma
    text = "date,current [A]\n" + "".join(f"2024-03-{d:02d},{2 + 0.01 * d}\n"
                                          for d in range(1, 13))
    f = tmp_path / "rig7.csv.xz"
    f.write_bytes(lzma.compress(text.encode()))
    (tr,) = read_table(f).trends
    assert (tr.actuator, len(tr.t)) == ("rig7", 12)
    monkeypatch.setattr("sys.stdin", io.StringIO(text))
    assert main(["hums", "prognose", "--trends", "-", "--failure", "2x"]) == 0
    out = capsys.readouterr().out
    assert "stdin: current [A], 12 tests, 2024-03-01 to 2024-03-12" in out
    # a pipe longer than the dialect's look-ahead (before: its early stop closed stdin)
    long = "day,current [A]\n" + "".join(f"{d},{2 + 0.001 * d}\n" for d in range(600))
    monkeypatch.setattr("sys.stdin", io.StringIO(long))
    assert main(["hums", "prognose", "--trends", "-", "--failure", "2x"]) == 0
    assert "stdin: current [A], 600 tests" in capsys.readouterr().out
    # a pipe on both sides: the JSON alone on standard output (before: a file named "-")
    monkeypatch.setattr("sys.stdin", io.StringIO(text))
    monkeypatch.chdir(tmp_path)
    assert main(["hums", "prognose", "--trends", "-", "--failure", "2x", "--json", "-"]) == 0
    got = capsys.readouterr()
    assert len(json.loads(got.out)["stdin"]) == 12
    assert "12 tests" in got.err and not (tmp_path / "-").exists()


def test_a_time_column_by_another_name(tmp_path):
    f = _write(tmp_path / "rig.csv", "Test Date,RMS current (A),note\n2024-03-01,2.1,3\n"
               "2024-03-02,2.2,4\n")
    tab = read_table(f)
    assert [(t.index, t.unit) for t in tab.trends] == [("RMS current", "A"), ("note", "")]
    assert tab.dates


def test_long_form_with_units_and_exposure(tmp_path):
    f = _write(tmp_path / "t.csv", "time,actuator,index,value,unit\n0,A,i,1.0,A\n1,A,i,1.1,A\n"
               "1,A,exposure,50,\n0,B,i,2.0,A\n")
    tab = read_table(f)
    assert [(t.actuator, t.index) for t in tab.trends] == [("A", "i"), ("B", "i")]
    assert tab.exposure["A"][1].tolist() == [50.0]
    assert tab.trends[0].t0 is None                       # numbers stay the file's days


@pytest.mark.parametrize("body, msg", [
    ("time,actuator,index,value\n0,A,i,1\n1,A,i,inf\n", ":3: value 'inf' is infinite"),
    ("time,actuator,index,value\n0,A,i,1e308\n", ":2: value '1e308' is beyond +-1e+100"),
    ("time,actuator,index,value\n0,A,i,-2e150\n", ":2: value '-2e150' is beyond +-1e+100"),
    ("time,actuator,index,value\n0,A,i,1\n2,A,i,1.2\n0,A,i,1.1\n",
     ":4: a second value of 'i' for actuator 'A' at time 0 (the first at line 2)"),
    ("time,actuator,index,value\n1e302,A,i,1\n", ":2: time '1e302' is out of range"),
    ("time,actuator,index,value\nnan,A,i,1\n", ":2: time 'nan' is out of range"),
    ("time,actuator,index,value\n0,A,i,1\n2024-01-01,A,i,2\n", "mixes numbers and dates"),
    ("date,x\n2024-01-01T00:00+00:00,1\n2024-01-02,2\n", "with and without a time zone"),
    ("time,actuator,index,value,unit\n0,A,i,1,A\n1,A,i,1,mA\n", "in unit 'mA' here, 'A'"),
    ("time,actuator,value\n0,A,1\n", "needs the columns"),
    ("when,x\n0,1\n", "no time column"),
    ("time,x,x\n0,1,2\n", "column 'x' appears twice"),
    ("time,x\n0,abc\n", ":2: value 'abc' is not a number"),
    ("time,x\n0,1,2\n", ":2: 3 fields, the header has 2"),
])
def test_bad_rows_are_one_line_naming_the_line(tmp_path, body, msg):
    f = _write(tmp_path / "t.csv", body)
    with pytest.raises(BenchError) as exc:
        read_table(f)
    assert msg in str(exc.value) and "\n" not in str(exc.value)


def _calibration(tmp_path):
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parents[1] / "integration"))
    from test_prognosis import synthetic_calibration
    cf = tmp_path / "cal.json"
    cf.write_text(json.dumps(synthetic_calibration().to_json()))
    return cf


@pytest.mark.parametrize("row, msg", [
    ("5,A,ci_harmonic,inf", "is infinite"),
    ("1,A,ci_harmonic,0.97", "a second value of 'ci_harmonic' for actuator 'A' at time 1"),
    ("1e300,A,ci_harmonic,0.97", "is out of range"),
])
def test_prognose_refuses_inf_merged_times_and_huge_times(tmp_path, capsys, row, msg):
    """Before: an inf value ran to a result with exit 0, the same time twice became one
    test with the mean of the two, times x 1e300 crashed in the resampling
    (ValueError, exit 1)."""
    cf = _calibration(tmp_path)
    f = _write(tmp_path / "t.csv", "time,actuator,index,value\n0,A,ci_harmonic,0.99\n"
               f"1,A,ci_harmonic,0.98\n2,A,ci_harmonic,0.97\n{row}\n")
    assert main(["hums", "prognose", "--trends", str(f), "--calibration", str(cf)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and msg in err and "\n" not in err, err


@pytest.mark.parametrize("which", ["trends", "calibration"])
def test_an_output_that_is_an_input_is_refused_before_any_work(tmp_path, capsys, which):
    """Before: `--json` equal to the trends file or to the calibration overwrote it."""
    cf = _calibration(tmp_path)
    f = _write(tmp_path / "t.csv", "time,actuator,index,value\n0,A,ci_harmonic,0.99\n"
               "1,A,ci_harmonic,0.98\n")
    target = f if which == "trends" else cf
    before = target.read_bytes()
    rc = main(["hums", "prognose", "--trends", str(f), "--calibration", str(cf), "--json",
               str(tmp_path / "." / target.name)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "would overwrite it" in err and "\n" not in err, err
    assert target.read_bytes() == before


def _trend_file(tmp_path, unit="A", n=12):
    rows = ["date,actuator,index,value,unit"]
    rng = np.random.default_rng(0)
    for k in range(n):
        rows.append(f"2024-01-{k + 1:02d},R1,rms,{2.0 + 0.05 * max(k - 5, 0) + rng.normal(0, 0.01):.4f},"
                    f"{unit}")
    return _write(tmp_path / "t.csv", "\n".join(rows) + "\n")


@pytest.mark.parametrize("argv, msg", [
    (["--failure", "1.5"], "--failure 1.5 (1.5 A) is below the healthy level 2"),
    (["--failure", "2.01"], "is within the healthy scatter"),
    (["--failure", "3", "--decreasing"], "is above the healthy level"),
    (["--failure", "4 mA"], "the unit 'mA' does not match the index's unit 'A'"),
    (["--unit", "mA"], "--unit 'mA' does not match the unit 'A' the file gives"),
    (["--healthy-tests", "1"], "--healthy-tests 1: a healthy spread needs at least 2 tests"),
    (["--healthy-tests", "2024-01-01"], "1 test(s) up to that date"),
    (["--failure", "3", "--warning", "3.5"], "--warning 3.5 is not before --failure 3"),
    (["--failure", "twice"], "give a level in the index's unit (4.6)"),
    (["--index", "nope"], "no index 'nope'"),
    (["--truth", "17"], "--truth '17': a time as the file gives them (a date)"),
])
def test_trend_options_that_cannot_hold_are_one_line(tmp_path, capsys, argv, msg):
    f = _trend_file(tmp_path)
    rc = main(["hums", "prognose", "--trends", str(f), *argv])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and msg in err and "\n" not in err, err


def test_fewer_tests_than_the_reference_is_a_stated_note(tmp_path, capsys):
    f = _trend_file(tmp_path, n=3)
    out = tmp_path / "e.json"
    assert main(["hums", "prognose", "--trends", str(f), "--failure", "2x", "--json",
                 str(out)]) == 0
    rows = json.loads(out.read_text())["R1"]
    assert len(rows) == 3 and all(r["rul_p50"] is None for r in rows)
    assert all("healthy reference incomplete: 3 of 5 tests" in r["notes"][0] for r in rows)
    said = capsys.readouterr().out
    assert said.count("healthy reference incomplete") == 1, said    # not again as a note


def test_no_spread_in_the_healthy_tests_is_one_line(tmp_path, capsys):
    f = _write(tmp_path / "t.csv", "day,x\n0,1\n1,1\n2,1\n3,1.5\n")
    assert main(["hums", "prognose", "--trends", str(f), "--healthy-tests", "3"]) == 2
    assert "all read 1: no spread" in capsys.readouterr().err


def test_not_utf8_names_the_offset_of_the_first_bad_byte(tmp_path):
    f = tmp_path / "t.csv"
    f.write_bytes(b"time,x\n0,1\n" + b"1,\xff\n")
    with pytest.raises(BenchError, match=r"byte 0xff at offset 13\)"):
        read_table(f)


def test_prognose_shows_its_progress_in_tests_and_actuators(tmp_path, capsys, monkeypatch):
    """Before: `bench hums prognose` on a large trends file printed nothing until the end
    (10^6 rows: minutes without output). Both paths now draw a tqdm bar (shown after
    a second): in tests on the trend's own path, in actuators on the calibrated one."""
    import tqdm as tqdm_module
    made = []
    real = tqdm_module.tqdm

    class Recorder(real):  # type: ignore[misc, valid-type]
        def __init__(self, *a, **k):
            made.append((k.get("desc"), k.get("unit"), k.get("total")))
            super().__init__(*a, **k)
    monkeypatch.setattr(tqdm_module, "tqdm", Recorder)
    cf = _calibration(tmp_path)
    f = _write(tmp_path / "t.csv", "time,actuator,index,value\n" + "".join(
        f"{d},{a},ci_harmonic,{1 - 0.01 * d:.3f}\n" for a in "AB" for d in range(4)))
    assert main(["hums", "prognose", "--trends", str(f), "--calibration", str(cf)]) == 0
    assert ("prognosis", "actuator", 2) in made
    g = _trend_file(tmp_path)
    from bench.signals import textlines
    monkeypatch.setattr(textlines, "BAR_BYTES", 1)     # the reading bar of a large file
    assert main(["hums", "prognose", "--trends", str(g), "--failure", "2x"]) == 0
    assert ("prognosis", "test", 12) in made
    assert (f"reading {g.name}", "B", g.stat().st_size) in made


def test_the_run_hands_each_chunk_over_and_keeps_the_order(monkeypatch):
    from bench.hums import trend_run
    from bench.hums.trend_io import Trend
    from bench.hums.trend_prognosis import Settings
    monkeypatch.setattr(trend_run, "CHUNK", 2)
    rng = np.random.default_rng(1)
    trends = [Trend(f"A{k}", "i", "", np.arange(8.0), 1 + rng.normal(0, 0.01, 8),
                    np.arange(8)) for k in range(5)]
    got = []
    trend_run.run(trends, Settings(healthy="3"), lambda r: got.append(r.trend.actuator),
                  workers=1, progress=False)
    assert got == [f"A{k}" for k in range(5)]
