"""Bad input to `bench hums prognose`, `bench hums sweep|rul|campaign --doc` and `bench
decode --period`: one `error: ...` line and exit 2, before any work, never an exception's
type in the message and never a file changed that the user did not name for it."""

from __future__ import annotations

import can
import pytest
from cli_errors import one_line, stub_steps
from log_frames import F, run, write_log

from bench import BenchError
from bench.cli import main
from bench.hums.trend_synth import endurance_trend, write_csv


@pytest.fixture
def trends(tmp_path):
    """A valid trends CSV: the synthetic exponential rise of seed 1."""
    path = tmp_path / "t.csv"
    write_csv([endurance_trend("exponential", 1)], path)
    return path


def _prognose(trends, *extra: str) -> int:
    return main(["hums", "prognose", "--trends", str(trends), "--healthy-tests", "5",
                 "--model", "trend", *extra])


@pytest.mark.parametrize("option, words", [
    ("--failure=1e308", ("--failure", "beyond +-1e+100")),
    ("--failure=1e101", ("--failure", "beyond +-1e+100")),
    ("--failure=1e100x", ("--failure", "beyond +-1e+100")),
    ("--failure=1e6", ("--failure", "healthy sd", "nearer level")),
    ("--warning=1e200", ("--warning", "beyond +-1e+100")),
])
def test_prognose_refuses_a_level_past_what_the_model_takes(trends, capsys, option, words):
    """--failure=1e308 ended in "ZeroDivisionError: float division by zero" (and 1e6 in
    "ValueError: attempt to get argmax of an empty sequence"): the degradation model
    works in units of the distance from healthy to failure, whose healthy noise then
    vanished in its arithmetic."""
    extra = [option] if option.startswith("--failure") else ["--failure", "2x", option]
    err = one_line(capsys, _prognose(trends, *extra), *words)
    assert "Error" not in err


def test_prognose_takes_a_far_failure_level_within_the_limit(trends, capsys):
    """The limit leaves room: a failure level a few thousand healthy sd away runs."""
    assert _prognose(trends, "--failure", "100") == 0
    assert "exponential-1" in capsys.readouterr().out


def test_prognose_names_the_line_a_field_too_large_is_on(tmp_path, capsys):
    """A 1 MB line without a newline ended in "Error: field larger than field limit
    (131072)" (csv.Error), exit 1."""
    path = tmp_path / "big.csv"
    path.write_text("time,actuator,index,value\n0,a,x,1\n" + "x" * 1_000_000)
    err = one_line(capsys, _prognose(path, "--failure", "2x"), f"{path}:3",
                   "not a readable CSV row", "field limit")
    assert "Error:" not in err


def test_prognose_names_a_header_too_large(tmp_path, capsys):
    path = tmp_path / "head.csv"
    path.write_text("x" * 1_000_000)
    one_line(capsys, _prognose(path), f"{path}:1", "not a readable CSV header")


def test_prognose_says_a_directory_is_one(tmp_path, capsys):
    """--trends DIR said "no trends file DIR", as if nothing were there."""
    err = one_line(capsys, _prognose(tmp_path), str(tmp_path), "is a directory")
    assert "no trends file" not in err


_DOC_STEPS = {"sweep": ("bench.hums.sweep", "run"),
              "rul": ("bench.hums.rul_run", "run_rul"),
              "campaign": ("bench.hums.campaign", "run_campaign")}


@pytest.mark.parametrize("command", sorted(_DOC_STEPS))
def test_doc_must_be_a_markdown_file(tmp_path, capsys, monkeypatch, command):
    """`bench hums sweep --doc tdoc.csv` appended a markdown section to the CSV and
    exited 0. The runs are stand-ins that fail: the refusal comes before them."""
    stub_steps(monkeypatch, (_DOC_STEPS[command],), BenchError("the runs started"))
    doc = tmp_path / "tdoc.csv"
    doc.write_text("t,x\n0,1\n")
    err = one_line(capsys, main(["hums", command, "--doc", str(doc)]), "--doc",
                   "unknown suffix '.csv'", ".md")
    assert "the runs started" not in err
    assert doc.read_text() == "t,x\n0,1\n"


@pytest.mark.parametrize("name", ["page.md", "page.markdown", "PAGE.MD"])
def test_doc_takes_a_markdown_file(tmp_path, capsys, monkeypatch, name):
    stub_steps(monkeypatch, (_DOC_STEPS["sweep"],), BenchError("the runs started"))
    one_line(capsys, main(["hums", "sweep", "--doc", str(tmp_path / name)]),
             "the runs started")


def _sdo_period(us: int, t: float) -> list[can.Message]:
    """The ECU reading 0x1006 (communication cycle period, us) by an expedited upload."""
    return [can.Message(timestamp=t, arbitration_id=F.sdo_rx, is_extended_id=False,
                        data=bytes([0x40, 0x06, 0x10, 0, 0, 0, 0, 0])),
            can.Message(timestamp=t + 1e-4, arbitration_id=F.sdo_tx, is_extended_id=False,
                        data=bytes([0x43, 0x06, 0x10, 0]) + us.to_bytes(4, "little"))]


@pytest.mark.parametrize("period", ["1e308", "0.5", "5e-05"])
def test_decode_refuses_a_period_outside_the_bench_sync_range(tmp_path, capsys, period):
    """`bench decode h.log --period 1e308 -o p.csv` exited 0 with an overflow warning
    and infinite times."""
    log = tmp_path / "h.log"
    write_log(str(log), run(20))
    out = tmp_path / "p.csv"
    one_line(capsys, main(["decode", str(log), "--period", period, "-o", str(out)]),
             "--period", "0.0001 to 0.1 s", "sim.sync_period_s")
    assert not out.exists()


def test_decode_notes_a_period_other_than_the_logs_own(tmp_path, capsys):
    """A --period other than the log's SDO 0x1006 period was used without a word; it is
    still used (as docs/bus.md says), with a one-line note."""
    log = tmp_path / "h.log"
    write_log(str(log), _sdo_period(1000, 998.0) + run(30))
    out = tmp_path / "p.csv"
    assert main(["decode", str(log), "--period", "0.002", "-o", str(out)]) == 0
    notes = [n for n in capsys.readouterr().err.splitlines() if "note:" in n]
    assert notes == [f"{log}: note: --period 2 ms is used, not the SYNC period of 1 ms "
                     "the log's SDO traffic gives"]
    assert out.read_text().splitlines()[2].startswith("0.002")
    assert main(["decode", str(log), "--period", "0.001", "-o", str(out)]) == 0
    assert "note:" not in capsys.readouterr().err
