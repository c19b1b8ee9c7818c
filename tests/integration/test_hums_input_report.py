"""`bench hums report --period` against the log: a command period the log does not hold
once (`--period 1e308`, `--period 10` on a shorter log) exited 0 and called a healthy log
DEGRADED (the harmonic Ci needs one whole period; without it the broadband Ci, 0.897,
was judged); one of fewer samples than a period's indexes take is refused too."""

from __future__ import annotations

import pytest
from cli_errors import one_line
from sample_data import sine_logs

from bench.cli import main


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    return sine_logs(tmp_path_factory.mktemp("logs"))       # 3 cycles of 2 Hz: 1.5 s


@pytest.mark.parametrize("period, words", [
    ("1e308", ("--period 1e+308 s", "longer than the log", "(1.5 s)")),
    ("10", ("--period 10 s", "longer than the log", "(1.5 s)")),
    ("1.6", ("--period 1.6 s", "longer than the log")),
    ("0.005", ("--period 0.005 s", "fewer than 8 samples", "(one every 0.001 s")),
])
def test_report_refuses_a_period_the_log_cannot_hold(logs, tmp_path, capsys, period, words):
    out = tmp_path / "rep"
    rc = main(["hums", "report", "--out", str(out), str(logs / "healthy.npz"),
               "--period", period])
    one_line(capsys, rc, *words)
    assert not (out / "report.html").exists()


def test_report_takes_the_period_of_the_log(logs, tmp_path, capsys):
    """The command's own period, given: the healthy log stays healthy."""
    out = tmp_path / "rep"
    assert main(["hums", "report", "--out", str(out), str(logs / "healthy.npz"),
                 "--period", "0.5", "--no-rul"]) == 0
    assert "healthy.npz: HEALTHY" in capsys.readouterr().out
