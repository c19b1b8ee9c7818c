"""Inputs refused in one line before the work: a directory named as a log ("no such
file: DIR", as if it were missing), a load rating of 0 and of -1 (two messages for one
rule), and a sweep of 100000 points (300000 plant runs, no bound)."""

from __future__ import annotations

import pytest

from bench import BenchError


def _one_line(capsys, rc, words):
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and words in err[0], err


def test_a_directory_is_not_a_log(tmp_path, capsys):
    from bench.cli import main
    _one_line(capsys, main(["usage", str(tmp_path)]), "is a directory, not a log")
    _one_line(capsys, main(["hums", "report", str(tmp_path), "--out", str(tmp_path / "r")]),
              "is a directory, not a log")


@pytest.mark.parametrize("value", ["0", "-1", "nan"])
def test_a_load_rating_must_be_above_0_in_one_message(tmp_path, capsys, value):
    from bench.cli import main
    log = tmp_path / "x.log"
    log.write_text("")
    _one_line(capsys, main(["usage", str(log), f"--load-rating-n={value}"]),
              "--load-rating-n must be a finite number of newtons > 0")


def test_a_sweep_has_a_largest_number_of_points():
    from bench.hums import sweep as S
    with pytest.raises(BenchError, match="2 to 201 degradation points"):
        S.run(points=100000, noise="off")
