"""The HUMS report shows one value per quantity: its summary table, its per-log tables,
its JSON and the command line agree on Ci (the judged one, `bench.hums.verdict.judged_ci`),
and the RUL part reads as what it is (figure, words, why there is none)."""

from __future__ import annotations

import json
from html.parser import HTMLParser

import numpy as np
import pytest
from sample_data import sine_logs

from bench.bus.logs import load_trace
from bench.cli import main
from bench.hums import fusion as F
from bench.hums import report as HR
from bench.hums.rul import Prediction


class _Tables(HTMLParser):
    """Every <table> of a page as rows of cell texts."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[list[list[str]]] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.tables[-1][-1].append(" ".join("".join(self._cell).split()))
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


@pytest.fixture(scope="module")
def noisy_logs(tmp_path_factory):
    """Two noisy 2 Hz sines, healthy and worn: the broadband Ci reads ~0.07-0.1 below
    the judged one, so a page that shows the wrong one fails."""
    return sine_logs(tmp_path_factory.mktemp("logs"))


def test_summary_table_matches_the_json_and_the_command_line(noisy_logs, tmp_path, capsys):
    out = tmp_path / "rep"
    logs = [str(noisy_logs / "healthy.npz"), str(noisy_logs / "worn.npz")]
    assert main(["hums", "report", *logs, "--no-rul", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    js = {x["log"]: x for x in json.loads((out / "indexes.json").read_text())}
    page = _Tables()
    page.feed((out / "report.html").read_text())
    summary = page.tables[0]
    col = summary[0].index("Ci")
    for row in summary[1:]:
        log = js[row[0]]
        ci, broadband = log["indexes"]["ci"], log["indexes"]["ci_broadband"]
        assert abs(ci - broadband) > 0.03          # the two readings are told apart
        assert row[col] == f"{ci:.3f}" == f"{log['summary']['ci']:.3f}"
        assert row[summary[0].index("verdict")] == log["verdict"]
        assert f"{row[0]}: {log['verdict']}; Ci = {ci:.3f}" in said
        # the log's own table: Ci the same number, the broadband one under its own name
        own = next(t for t in page.tables[2:] if ["Ci broadband", f"{broadband:.3f}",
                                                  "eq. 6.6, whole spectrum"] in t
                   and any(r[:2] == ["Ci", f"{ci:.3f}"] for r in t))
        assert sum(r[0] == "Ci" for r in own) == 1
    healthy = js["healthy.npz"]
    assert healthy["verdict"] == "HEALTHY" and healthy["indexes"]["ci"] >= 0.93
    assert healthy["rul"].startswith("not computed: skipped here")
    text = (out / "report.html").read_text()
    assert "needs a periodic log" not in text
    from bench.reports import stylesheet
    assert stylesheet() in text and text.count("<style>") == 1     # the reports' base page


def _predictions() -> list[Prediction]:
    """Four predictions: finite median with an infinite upper bound, then three whose
    median is infinite (more than half the fits never reach b_fail) with a lower bound
    of ~1800 s."""
    out = []
    for k, t in enumerate((7.0, 8.0, 9.0, 10.0)):
        n_inf = 80 if k == 0 else 140
        finite = t + np.linspace(300.0 if k == 0 else 1800.0, 3000.0, 200 - n_inf)
        out.append(Prediction(t, np.concatenate([finite, np.full(n_inf, np.inf)])))
    return out


def test_rul_figure_has_a_median_and_a_band_upright(noisy_logs, monkeypatch):
    """The RUL figure: a median line where the median is finite, a marker where it is
    not, and a band whose upper edge is nowhere below its lower one (both clipped alike);
    the words say 'no failure predicted' and why, never 'inf'."""
    from matplotlib.figure import Figure
    a = HR.analyse(load_trace(noisy_logs / "worn.npz"), "worn.npz", rul=False)
    b = [10.0 * k for k in range(11)]
    cal = F.Calibration(b, {}, [1 - 0.0046 * x for x in b], {}, {}, {}, 0.98, 0.8, 89.7)
    est = np.full(len(a.period_table["ci"]), 50.0)
    a.fused = (F.FusedResult(est, est, 0.5, _predictions()), cal, np.arange(len(est)))
    drawn: list = []
    monkeypatch.setattr(Figure, "savefig", lambda self, *x, **k: drawn.append(self))
    HR.render([a])
    fig = next(f for f in drawn if any("remaining useful life" in ax.get_title()
                                       for ax in f.axes))
    ax = fig.axes[0]
    v = ax.collections[0].get_paths()[0].vertices     # fill_between(t, lower, upper):
    n = (len(v) - 3) // 2                              # start, lower, end, upper reversed
    lower, upper = v[1:1 + n, 1], v[2 + n:2 + 2 * n, 1][::-1]
    assert n == 4 and np.all(np.isfinite(v)) and np.all(upper >= lower)
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    median = lines["RUL, median"].get_ydata()
    assert np.isfinite(median[0]) and np.isnan(median[1:]).all()
    assert len(lines["median: no failure predicted"].get_xdata()) == 3
    text = HR._rul_text(a)
    assert "inf" not in text and text.startswith("no failure predicted at t = 10.0 s")
    p = a.fused[0].predictions[-1]
    assert "does not grow measurably" in text
    assert f"within {p.band()[0] - p.t_pred_s:.0f} s" in text


def test_no_rul_figure_when_no_prediction_reaches_failure(noisy_logs, monkeypatch):
    """Every fit short of failure (all inf): the words say so; no empty frame whose
    axis reads 0 to 1 s with only markers at its top."""
    from matplotlib.figure import Figure
    a = HR.analyse(load_trace(noisy_logs / "worn.npz"), "worn.npz", rul=False)
    b = [10.0 * k for k in range(11)]
    cal = F.Calibration(b, {}, [1 - 0.0046 * x for x in b], {}, {}, {}, 0.98, 0.8, 89.7)
    est = np.full(len(a.period_table["ci"]), 50.0)
    never = [Prediction(t, np.full(200, np.inf)) for t in (7.0, 8.0, 9.0, 10.0)]
    a.fused = (F.FusedResult(est, est, 0.5, never), cal, np.arange(len(est)))
    drawn: list = []
    monkeypatch.setattr(Figure, "savefig", lambda self, *x, **k: drawn.append(self))
    page = HR.render([a])
    assert drawn and not any("remaining useful life" in ax.get_title()
                             for f in drawn for ax in f.axes)
    assert "Remaining useful life (fused predictor)" not in page
    assert HR._rul_text(a).startswith("no failure predicted at t = 10.0 s")
