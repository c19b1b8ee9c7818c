"""Inputs refused in one line before the work (each found by running the commands on
bad input): a --json or --markdown over a file of another kind (it replaced a candump log
with JSON), the same bytes given twice under two names (a table and its copy made a
baseline of every run twice), runs asked for that a table lacks (dropped without a
word), --params beside --actuator (ignored), a set-point frequency no SYNC rate holds
(a sine at 1 MHz sampled at 1 kHz is 0 at every sample), imported values beyond any
measurement (written, then refused by every reader), a ready file in a folder that
takes none, and a column map nested too deep (RecursionError)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from plant_rt import cli as plant_cli

SAMPLE = Path(__file__).resolve().parents[1] / "data" / "cranfield_sample"
HEALTHY = SAMPLE / "normal_load40_runs1-4.csv.xz"


def _one_line(capsys, rc, *words):
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and err and err[-1].startswith("error: "), err
    for w in words:
        assert w in err[-1], err


def test_a_json_output_must_be_a_json_file(tmp_path, capsys):
    from bench.cli import main
    log = tmp_path / "run.log"
    log.write_text("(1000.000000) vcan0 080#\n")
    before = log.read_bytes()
    _one_line(capsys, main(["hums", "fit", "--json", str(log)]), "--json", "unknown suffix",
              "(use .json)")
    _one_line(capsys, main(["gap-bench", "--markdown", str(tmp_path / "b.csv")]),
              "--markdown", "(use .md, .markdown)")
    assert log.read_bytes() == before


def test_the_same_bytes_under_two_names_are_one_input(tmp_path, capsys):
    from bench.cli import main
    copy = tmp_path / "copy.csv.xz"
    shutil.copy(HEALTHY, copy)
    _one_line(capsys, main(["rig", "baseline", str(HEALTHY), str(copy), "--runs", "1,2",
                            "--lead-mm", "5", "-o", str(tmp_path / "b.json")]),
              "hold the same bytes")


def test_runs_a_table_lacks_are_refused(tmp_path, capsys):
    from bench.cli import main
    _one_line(capsys, main(["rig", "baseline", str(HEALTHY), "--runs", "1,2,99",
                            "--lead-mm", "5", "-o", str(tmp_path / "b.json")]),
              "no cycle of run(s) 99", "they have run(s) 1,2,3,4")
    _one_line(capsys, main(["rig", "baseline", str(HEALTHY), "--runs", "1-9999999",
                            "--lead-mm", "5", "-o", str(tmp_path / "b.json")]),
              "more than 10000 runs")


def test_params_beside_an_actuator_description_is_refused(tmp_path, capsys):
    from bench.cli import main
    log = tmp_path / "h.csv"
    log.write_text("t\n")
    _one_line(capsys, main(["calibrate", str(log), "--actuator", "cranfield", "--params",
                            "nope", "-o", str(tmp_path / "c.json")]), "--params")


@pytest.mark.parametrize("f", ["1e6", "1e308", "0"])
def test_a_sine_no_sync_rate_holds_is_refused(capsys, f):
    from bench.cli import main
    _one_line(capsys, main(["run", "sine", "--duration", "0.2", "--frequency-hz", f]),
              "--frequency-hz", "below 5000 Hz")


@pytest.mark.parametrize("flag", ["--f0-hz", "--f1-hz"])
def test_a_chirp_no_sync_rate_holds_is_refused(capsys, flag):
    """A chirp's end frequencies are set-point frequencies too: one a SYNC-sampled
    set-point cannot hold is refused before the run starts, as a sine's is."""
    from bench.cli import main
    _one_line(capsys, main(["run", "chirp", "--duration", "0.2", flag, "1e6"]),
              flag, "below 5000 Hz")


def test_an_import_beyond_any_measurement_is_refused(tmp_path, capsys):
    from bench.cli import main
    (tmp_path / "t.csv").write_text("t,i\n" + "\n".join(f"{k * 0.01},1e308" for k in range(5)))
    (tmp_path / "m.csv").write_text("signal,column,unit,scale\nt_s,t,s,\ncurrent_a,i,A,\n")
    out = tmp_path / "x.npz"
    _one_line(capsys, main(["import", str(tmp_path / "t.csv"), "--map", str(tmp_path / "m.csv"),
                            "-o", str(out)]), "beyond any measurement")
    assert not out.exists()


def test_a_column_map_nested_too_deep_is_one_line(tmp_path, capsys):
    from bench.cli import main
    (tmp_path / "t.csv").write_text("t,i\n0,1\n0.01,2\n")
    (tmp_path / "m.json").write_text("[" * 100000 + "]" * 100000)
    _one_line(capsys, main(["import", str(tmp_path / "t.csv"), "--map",
                            str(tmp_path / "m.json"), "-o", str(tmp_path / "x.npz")]),
              "nested too deep")


def test_a_ready_file_in_a_folder_that_takes_none(capsys):
    """/proc takes no new file, though os.access says it is writable to root."""
    _one_line(capsys, plant_cli.main(["--duration", "1", "--ready-file", "/proc/x"]),
              "not writable")
