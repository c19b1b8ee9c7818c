"""Paths a command is given, checked before it works (`bench.cli.outputs.check_io`, and
`bench gap`'s own checks): an empty path, one input file given twice, a held-out log that
is the log itself, and a fundamental the log's samples cannot show are each one line."""

from __future__ import annotations

import shutil

import pytest

from bench.gap.resim import FAST
from bench.profiles.maneuvers import compact
from bench.sim.harness import simulate
from plant_rt.params import PlantParams


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    p = tmp_path_factory.mktemp("paths") / "run.npz"
    base = PlantParams().with_dict({**FAST, "sensors.noise": True, "sensors.noise_seed": 4})
    simulate(compact(), base).measured().save(p)
    return p


def _one_line(capsys, rc, *words):
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("error: "), err
    for w in words:
        assert w in err[0], err


def test_an_empty_output_path_is_refused(tmp_path, capsys, log, monkeypatch):
    """`--out ""` wrote the report into the current folder; `-o ""` wrote nothing, exit 0."""
    from bench.cli import main
    monkeypatch.chdir(tmp_path)
    _one_line(capsys, main(["hums", "report", str(log), "--out", ""]), "--out: an empty path")
    _one_line(capsys, main(["gap", str(log), "--json", " "]), "--json: an empty path")
    assert list(tmp_path.iterdir()) == []


def test_one_input_given_twice_is_refused(tmp_path, capsys, log):
    """`bench usage a.log a.log` summed one run's usage twice (under another name too)."""
    from bench.cli import main
    other = tmp_path / "same.npz"
    other.symlink_to(log)
    _one_line(capsys, main(["usage", str(log), str(other), "--by-actuator"]), "given twice")


def test_gap_refuses_the_log_as_its_own_holdout(tmp_path, capsys, log):
    """`bench gap LOG --holdout LOG` scored the held-out shrink on the fitted data."""
    from bench.cli import main
    copy = tmp_path / "copy.npz"
    shutil.copy(log, copy)
    _one_line(capsys, main(["gap", str(log), "--holdout", str(copy)]),
              "the same content as the fitted log")


def test_gap_refuses_a_fundamental_above_the_logs_nyquist(capsys, log):
    """`--fundamental 1e308` was taken: every band below it, exit 0."""
    from bench.cli import main
    _one_line(capsys, main(["gap", str(log), "--fundamental", "1e308"]), "Nyquist")
