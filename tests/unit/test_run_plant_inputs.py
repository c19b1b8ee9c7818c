"""Numbers and files `bench run` and the plant node are given, refused before the bus
opens: an infinite duration (it ended in "OverflowError: cannot convert float infinity
to integer"), a set-point beyond any travel (clamped without a word), a ready file that
is a log (the node wrote "ready" over 1.4 MB of it) and a binary parameter file
("UnicodeDecodeError")."""

from __future__ import annotations

from plant_rt import cli as plant_cli


def _one_line(capsys, rc, words):
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and words in err[0], err


def test_run_refuses_an_endless_duration_and_a_set_point_beyond_any_travel(capsys):
    from bench.cli import main
    _one_line(capsys, main(["run", "step", "--duration", "1e308"]), "--duration must be")
    _one_line(capsys, main(["run", "step", "--duration", "1", "--amplitude-m", "1e308"]),
              "beyond any actuator's travel")


def test_the_plant_keeps_a_file_that_is_not_a_ready_file(tmp_path, capsys):
    log = tmp_path / "run.log"
    log.write_text("(0.000000) vcan0 710#00\n" * 1000)
    before = log.read_bytes()
    _one_line(capsys, plant_cli.main(["--duration", "1", "--ready-file", str(log)]),
              "is not a ready file")
    assert log.read_bytes() == before
    _one_line(capsys, plant_cli.main(["--duration", "1", "--ready-file",
                                      str(tmp_path / "no" / "r")]), "does not exist")


def test_the_plant_refuses_a_binary_parameter_file(tmp_path, capsys):
    bad = tmp_path / "p.json"
    bad.write_bytes(b"\xa1\xff\x00")
    _one_line(capsys, plant_cli.main(["--duration", "1", "--params", str(bad)]),
              "not a parameter file")
