"""`bench decode` and the log reader on bad input: bad lines are
streamed (counted, the first few kept: memory bounded), a log with nothing to decode is a
one-line error with a non-zero exit, and the damage found is printed."""

from __future__ import annotations

import random
import tracemalloc

import can
import pytest
from log_frames import T0, F, at, run, where, write_log

from bench import BenchError
from bench.bus.logs import LogIssues, read_log, trace_from_log
from bench.cli import main


def _garbage(path, n_lines: int, seed: int = 1) -> None:
    r = random.Random(seed)
    alpha = "abcdefghijklmnopqrstuvwxyz0123456789 #()."
    path.write_text("".join("".join(r.choice(alpha) for _ in range(r.randint(10, 70))) + "\n"
                            for _ in range(n_lines)))


def _peak_bytes(fn) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_bad_lines_are_counted_but_only_the_first_ones_kept(tmp_path):
    log = tmp_path / "garbage.log"
    _garbage(log, 20_000)
    issues = LogIssues(20)
    peak = _peak_bytes(lambda: list(read_log(log, issues)))
    assert len(issues) == 20_000 and len(list(issues)) == 20
    assert [i.line for i in issues][:3] == [1, 2, 3]
    assert peak < 1_000_000, f"{peak / 1e6:.1f} MB for 20,000 bad lines"


def test_decoding_a_log_of_bad_lines_is_bounded_and_an_error(tmp_path):
    log = tmp_path / "garbage.log"
    _garbage(log, 20_000)

    def decode():
        with pytest.raises(BenchError, match=r"nothing to decode.*20000 bad lines \(line 1: "):
            trace_from_log(log)
    assert _peak_bytes(decode) < 2_000_000


def test_a_line_without_end_is_read_in_bounded_pieces(tmp_path):
    log = tmp_path / "one-line.log"
    log.write_text("(1.000000) vcan0 080#01 T\n" + "A" * 3_000_000)
    issues: list = []
    peak = _peak_bytes(lambda: list(read_log(log, issues)))
    assert [(i.line, i.reason) for i in issues] == [(2, "line longer than 4096 characters")]
    assert peak < 1_000_000


def test_decode_exits_non_zero_with_one_line_when_nothing_decodes(tmp_path, capsys):
    log = tmp_path / "garbage.log"
    _garbage(log, 500)
    assert main(["decode", str(log)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, err
    assert "500 bad lines" in err and "Traceback" not in err
    only_sdo = tmp_path / "sdo.log"
    only_sdo.write_text("(1.000000) vcan0 610#4000100000000000 T\n")
    assert main(["decode", str(only_sdo)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "no SYNC" in err


def test_decode_prints_what_the_log_lost_and_repeated(tmp_path, capsys):
    seq = run(30)
    del seq[where(seq, 4, "EMA_TPDO1")]
    del seq[where(seq, 9, "SYNC")]
    lo = where(seq, 20, "SYNC")
    del seq[lo:lo + 6]
    i = where(seq, 12, "EMA_TPDO3")
    seq.insert(i + 1, at(can.Message(arbitration_id=seq[i].arbitration_id,
                                      data=bytes(seq[i].data), is_extended_id=False),
                          seq[i].timestamp + 3e-6))
    log = tmp_path / "damaged.log"
    write_log(log, seq)
    with log.open("a") as fh:          # a heartbeat stamped 2 s before the end of the log
        fh.write(f"({T0 - 2.0:.6f}) vcan0 {F.cob['EMA_Heartbeat']:03X}#05 R\n")
    assert main(["decode", str(log)]) == 0
    out = capsys.readouterr().out
    assert "2 lost SYNCs (1 recovered from its frames)" in out, out
    assert "1 duplicate frame dropped" in out
    assert "missing: ECU_Setpoint in 1 period, EMA_TPDO1 in 2 periods" in out
    assert "1 frame out of time order: decoded in time-stamp order" in out


def test_garbage_sync_counters_are_refused_not_grown_into_rows(tmp_path, capsys):
    """Each SYNC counter jump stands for up to 239 lost SYNCs (empty rows): 5000 SYNC
    lines of random counters would make ~600,000 rows; they are refused instead."""
    r = random.Random(2)
    log = tmp_path / "syncs.log"
    log.write_text("".join(f"({T0 + k * 1e-3:.6f}) vcan0 080#{r.randint(1, 240):02X} T\n"
                           for k in range(5000)))
    assert _peak_bytes(lambda: pytest.raises(BenchError, trace_from_log, log)) < 2_000_000
    assert main(["decode", str(log)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: the SYNC counters make no sense: ") and \
        len(err.splitlines()) == 1


@pytest.mark.parametrize("extra, msg", [
    (["--period", "inf"], "--period must be a finite number of seconds > 0, not inf"),
    (["--period", "-1"], "--period must be a finite number of seconds > 0, not -1"),
    (["--period", "0"], "--period must be a finite number of seconds > 0, not 0"),
    (["--counts-per-rev", "0"], "--counts-per-rev must be >= 1, not 0"),
    (["-o", "{tmp}/missing/out.csv"], "-o: cannot write {tmp}/missing/out.csv: directory "
                                      "{tmp}/missing does not exist"),
])
def test_decode_refuses_bad_options_before_reading_the_log(tmp_path, capsys, extra, msg):
    """Found by fuzzing: `--period inf` or `-1` printed "2000 SYNC periods of
    inf ms" (or -1000 ms) and exited 0; `--period 0` and `--counts-per-rev 0` were taken
    for "not given"; an -o into a missing directory failed after the decoding (exit 1,
    FileNotFoundError)."""
    log = write_log(tmp_path / "a.log", run(20))
    argv = ["decode", str(log), *(a.format(tmp=tmp_path) for a in extra)]
    assert main(argv) == 2
    assert capsys.readouterr().err.strip() == f"error: {msg.format(tmp=tmp_path)}"
