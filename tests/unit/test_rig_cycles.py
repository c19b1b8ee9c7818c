"""Reading a rig's table into cycles (`bench.rig.cycles.read_cycles`) when the table is
damaged: a header only, a text or blank cell in a signal or a key column, a repeated row,
a time that does not advance. Every lost cell, row or cycle is named with its line; a
cycle is never merged into another one nor split at a step the rig never made."""

from __future__ import annotations

import numpy as np
import pytest

from bench import BenchError
from bench.rig.cycles import read_cycles

HEADER = "set_point,position_error,current,profile,load,run,group,time"
N = 30                                   # samples per cycle: out, dwell at the top, in


def rows(runs=(1, 2), cycles_per_run=2, load="40") -> list[list[str]]:
    """A Cranfield-shaped table's rows (as text cells): per run `cycles_per_run` cycles of
    N samples, numbered on from 51, time restarting at 0 every cycle."""
    sp = np.r_[np.linspace(20, 140, 12), np.full(6, 140.0), np.linspace(140, 20, 12)]
    out = []
    group = 50
    for run in runs:
        for _ in range(cycles_per_run):
            group += 1
            for k in range(N):
                out.append([f"{sp[k]:.3f}", f"{0.01 * k:.3f}", f"{0.5 + 0.001 * k:.4f}",
                            "trap", load, str(run), str(group), f"{0.04 * k:.2f}"])
    return out


def write(tmp_path, table: list[list[str]], name="t.csv", header=HEADER):
    p = tmp_path / name
    p.write_text("\n".join([header] + [",".join(r) for r in table]) + "\n")
    return p


def line(row: int) -> int:
    """The CSV line of data row `row` (the header is line 1)."""
    return row + 2


COL = {k: i for i, k in enumerate(HEADER.split(","))}


def test_a_header_only_table_is_one_line(tmp_path):
    """A header-only CSV raised IndexError (cycles.py indexed the first row)."""
    with pytest.raises(BenchError, match=r"t\.csv: the table has a header but no rows"):
        read_cycles(write(tmp_path, []))


def test_a_text_cell_in_the_current_is_named_and_only_its_cycle_is_lost(tmp_path):
    """One text cell made the whole current column vanish ("the table has no column(s)
    current"). Now the cell is read as missing, with its line, and its cycle is not read
    like any cycle with a gap; the other cycles are read."""
    t = rows()
    t[N + 5][COL["current"]] = "abc"
    lost: list[str] = []
    cyc = read_cycles(write(tmp_path, t), skipped=lost)
    assert [c.group for c in cyc] == [51, 53, 54]
    assert lost == [f"t.csv: column current: 1 cell(s) not a number (line {line(N + 5)}: "
                    "'abc'): read as missing",
                    "t load 40 run 1 cycle 52: samples 1 without current: not read"]


def test_a_text_run_cell_does_not_merge_the_runs(tmp_path):
    """A text cell in `run` dropped the column and every cycle became run 0 (a baseline of
    four runs said "runs 0", no thresholds, exit 0)."""
    t = rows(runs=(1, 2, 3), cycles_per_run=2)
    t[2 * N + 3][COL["run"]] = "x"
    lost: list[str] = []
    cyc = read_cycles(write(tmp_path, t), skipped=lost)
    assert [(c.run, c.group) for c in cyc] == [(1, 51), (1, 52), (2, 54), (3, 55), (3, 56)]
    assert lost[-1] == (f"t load 40 run 2 cycle 53: run 'x' is not a number at line "
                        f"{line(2 * N + 3)}: not read")


@pytest.mark.parametrize("row, cell, why", [
    (3 * N + 7, "forty", "load 'forty' is not a number at line {}"),
    (3 * N, "", "no load at line {}"),           # blank, at the cycle's first row
])
def test_a_bad_load_cell_names_its_line_and_cycle(tmp_path, row, cell, why):
    """A text or blank load cell gave "no thresholds for load nan", or blamed the first
    cycle of the table ("cycle 51: the cycle has no load")."""
    t = rows()
    t[row][COL["load"]] = cell
    lost: list[str] = []
    cyc = read_cycles(write(tmp_path, t), skipped=lost)
    assert [c.group for c in cyc] == [51, 52, 53] and {c.load for c in cyc} == {40.0}
    assert lost[-1] == f"t load 40 run 2 cycle 54: {why.format(line(row))}: not read"


@pytest.mark.parametrize("col, row, cycle, why", [
    ("run", 2 * N, 53, "no run at line {}"),             # the cycle's first row
    ("group", N + 10, 52, "no group at line {}"),        # the middle of a cycle
])
def test_a_blank_run_or_group_cell_loses_its_cycle_only(tmp_path, col, row, cycle, why):
    """A blank run at a cycle's start, or a blank group, raised "ValueError: cannot convert
    float NaN to integer"."""
    t = rows()
    t[row][COL[col]] = ""
    lost: list[str] = []
    cyc = read_cycles(write(tmp_path, t), skipped=lost)
    assert [c.group for c in cyc] == sorted({51, 52, 53, 54} - {cycle})
    assert lost == [f"t load 40 run {1 + (cycle > 52)} cycle {cycle}: "
                    f"{why.format(line(row))}: not read"]


def test_a_blank_group_between_two_cycles_loses_both(tmp_path):
    """A row without a cycle number between two cycles may be the last of one or the first
    of the next: neither is read as if complete."""
    t = rows()
    t[2 * N - 1][COL["group"]] = ""
    lost: list[str] = []
    cyc = read_cycles(write(tmp_path, t), skipped=lost)
    assert [c.group for c in cyc] == [51, 54]
    assert lost == [f"t load 40 run 1 cycle 52: no group at line {line(2 * N - 1)}: not read",
                    f"t load 40 run 2 cycle 53: no group at line {line(2 * N - 1)}, just "
                    "before the cycle: not read"]


def test_an_exactly_repeated_row_is_dropped_with_a_note(tmp_path):
    """One repeated row broke the out-stroke in two (a set-point step of 0) and the
    complete cycle was called incomplete ("out 100 of 124 samples")."""
    t = rows()
    t.insert(N + 4, list(t[N + 3]))
    lost: list[str] = []
    cyc = read_cycles(write(tmp_path, t), skipped=lost)
    assert [len(c) for c in cyc] == [N] * 4
    assert lost == [f"t load 40 run 1 cycle 52: line {line(N + 4)} repeats line "
                    f"{line(N + 3)} exactly: dropped (the cycle is read without it)"]


def test_a_time_that_does_not_advance_loses_the_cycle(tmp_path):
    t = rows()
    t.insert(N + 4, list(t[N + 3]))
    t[N + 4][COL["current"]] = "2.5"
    lost: list[str] = []
    cyc = read_cycles(write(tmp_path, t), skipped=lost)
    assert [c.group for c in cyc] == [51, 53, 54]
    assert lost == [f"t load 40 run 1 cycle 52: time does not advance at line {line(N + 4)} "
                    f"(0.12, as at line {line(N + 3)}): not read"]


def test_no_cycle_left_says_why(tmp_path):
    """A table whose only cycle had a gap gave "no complete motion cycle in the table" and
    nothing else: the reason was printed only for tables that had a cycle left."""
    t = rows(runs=(1,), cycles_per_run=1)
    t[5][COL["current"]] = "nan"
    with pytest.raises(BenchError, match=r"no complete motion cycle in the table \(t load 40 "
                                         r"run 1 cycle 51: samples 1 without current"):
        read_cycles(write(tmp_path, t))


def test_a_table_without_a_load_column_says_so(tmp_path):
    t = [r[:COL["load"]] + r[COL["load"] + 1:] for r in rows()]
    lost: list[str] = []
    cyc = read_cycles(write(tmp_path, t, header=HEADER.replace("load,", "")), skipped=lost)
    assert len(cyc) == 4 and np.isnan(cyc[0].load)
    assert cyc[0].label == "t load unknown run 1 cycle 51"
    assert lost == ["t.csv: no load column: the cycles' load is unknown"]


def test_a_line_number_counts_the_blank_lines_before_it(tmp_path):
    """The CSV reader skips blank lines, and the message counted data rows from the
    header as if there were none: a text cell after a blank line was named one line too
    early (line 52 for a cell on line 53), and a repeated row likewise."""
    t = rows()
    t[N + 5][COL["current"]] = "abc"
    text = [HEADER] + [",".join(r) for r in t]
    text.insert(11, "")                   # a blank line after data row 9 (line 11)
    text.insert(3, "\r")                  # and an empty CRLF line after data row 1
    p = tmp_path / "t.csv"
    p.write_text("\n".join(text) + "\n")
    lost: list[str] = []
    read_cycles(p, skipped=lost)
    assert text[line(N + 5) + 1] == ",".join(t[N + 5])      # its line, two blanks later
    assert lost[0] == (f"t.csv: column current: 1 cell(s) not a number (line "
                       f"{line(N + 5) + 2}: 'abc'): read as missing")
