"""Bad input to `bench rig` (and a damaged baseline given to `bench gap` and `bench hums
report`), CLI in-process on the shipped Cranfield sample (tests/data/cranfield_sample,
lead 5 mm): every refusal is one `error:` line on stderr and exit code 2, before any
work, never a result judged against nothing.

A baseline whose thresholds are NaN, infinite, negative or all 0 judged the spall table's
10 cycles healthy (the real baseline flags all 10); --alpha 1e-300 wrote every threshold
as a bare `Infinity`; a lead of 1e308 or 1e-300 mm and an injected fault of 1e308 spreads
were taken; a directory given as a model was "no such model"."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import pytest
from sample_data import HEALTHY, SAMPLE, SPALLING, cranfield_baseline, import_cycles

from bench import BenchError
from bench.cli import main
from bench.cli import rig as R
from bench.rig.inject import SIZE_MAX

SPALL_CYCLE = "load=40_run=1_group=51.parquet"      # spalling stage 5, run 1, first cycle


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """The healthy baseline of runs 1 and 2 (base.json) and the spall table's cycles as
    `bench import` traces (s/)."""
    d = tmp_path_factory.mktemp("riginput")
    cranfield_baseline(d / "base.json")
    import_cycles(SPALLING, d / "s")
    return d


def _cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of `bench ARGS`; argparse's refusals exit 2 too."""
    try:
        rc = main([str(a) for a in args])
    except SystemExit as exc:
        rc = exc.code if isinstance(exc.code, int) else 2
    out, err = capsys.readouterr()
    return rc, out, err.strip()


def _refused(rc: int, err: str, *words: str) -> None:
    """One `error:` line, exit 2, every word in it, no exception type named."""
    assert rc == 2, err
    assert err.startswith("error: ") and len(err.splitlines()) == 1, err
    assert "Error:" not in err and "Traceback" not in err, err
    for w in words:
        assert w in err, err


def _damaged(data: Path, tmp_path: Path, value: float, anchor: bool = False) -> Path:
    """base.json with every threshold (or only the first runs' kept for --update) set to
    `value`."""
    d = json.loads((data / "base.json").read_text())
    tables = [d["store"]["anchor"]] if anchor else [d["thresholds"]]
    for table in tables:
        for cal in table.values():
            cal["thresholds"] = {k: value for k in cal["thresholds"]}
    out = tmp_path / "bad.json"
    out.write_text(json.dumps(d))
    return out


def test_the_real_baseline_flags_every_spall_cycle(data, capsys):
    rc, out, _ = _cli(["rig", "assess", SAMPLE / SPALLING, "--baseline", data / "base.json",
                       "-q"], capsys)
    assert rc == 0 and "10 / 10 cycles flagged" in out


@pytest.mark.parametrize("value, words", [
    (math.nan, ("feature localised", "finite number >= 0")),
    (-1.0, ("feature localised", "finite number >= 0")),
    (math.inf, ("feature localised", "finite number >= 0")),
    (0.0, ("no threshold above 0",))])
def test_rig_assess_refuses_a_baseline_with_a_bad_threshold(data, tmp_path, capsys, value,
                                                            words):
    bad = _damaged(data, tmp_path, value)
    rc, out, err = _cli(["rig", "assess", SAMPLE / SPALLING, "--baseline", bad, "-q"],
                        capsys)
    _refused(rc, err, str(bad), "load 40", *words)
    assert "flagged" not in out


def test_rig_assess_refuses_a_bad_threshold_of_the_first_runs(data, tmp_path, capsys):
    bad = _damaged(data, tmp_path, math.nan, anchor=True)
    rc, _, err = _cli(["rig", "assess", SAMPLE / SPALLING, "--baseline", bad, "-q"], capsys)
    _refused(rc, err, str(bad), "load 40", "feature localised", "--update")


def test_a_feature_without_a_threshold_is_left_out_not_refused(data, tmp_path, capsys):
    """A feature a load's cycles cannot give has no entry (periodic without the lead):
    that is not damage."""
    d = json.loads((data / "base.json").read_text())
    for cal in d["thresholds"].values():
        del cal["thresholds"]["rattle"]
    part = tmp_path / "part.json"
    part.write_text(json.dumps(d))
    rc, out, _ = _cli(["rig", "assess", SAMPLE / SPALLING, "--baseline", part, "-q"], capsys)
    assert rc == 0 and "10 / 10 cycles flagged" in out


@pytest.mark.parametrize("value", [math.nan, -1.0])
def test_gap_refuses_a_baseline_with_a_bad_threshold(data, tmp_path, capsys, value):
    bad = _damaged(data, tmp_path, value)
    rc, out, err = _cli(["gap", data / "s" / SPALL_CYCLE, "--baseline", bad], capsys)
    _refused(rc, err, str(bad), "load 40", "finite number >= 0")
    assert "verdict" not in out


@pytest.mark.parametrize("value", [math.nan, -1.0])
def test_hums_report_refuses_a_baseline_with_a_bad_threshold(data, tmp_path, capsys, value):
    bad = _damaged(data, tmp_path, value)
    rc, _, err = _cli(["hums", "report", data / "s" / SPALL_CYCLE, "--baseline", bad,
                       "--out", tmp_path / "rep"], capsys)
    _refused(rc, err, str(bad), "load 40", "finite number >= 0")


def _rig(cmd: str, tmp_path: Path, *extra: str) -> list[str | Path]:
    """A `bench rig CMD` that would run on the sample, with `extra` options."""
    healthy = SAMPLE / HEALTHY
    return {
        "baseline": ["rig", "baseline", healthy, "--runs", "1,2", "-o", tmp_path / "b.json"],
        "study": ["rig", "study", SAMPLE, "--calibrate-runs", "1,2", "--holdout-runs", "3,4",
                  "-o", tmp_path / "study"],
        "inject": ["rig", "inject", healthy, "--calibrate-runs", "1,2", "--holdout-runs",
                   "3,4", "-o", tmp_path / "inj"],
        "train": ["rig", "train", healthy, SAMPLE / SPALLING, "-o", tmp_path / "m.skops"],
    }[cmd] + list(extra)


COMMANDS = ["baseline", "study", "inject", "train"]


@pytest.mark.parametrize("alpha", ["1e-300", "1e-7", "0", "0.5", "nan"])
@pytest.mark.parametrize("cmd", COMMANDS)
def test_alpha_out_of_range_is_refused(tmp_path, capsys, cmd, alpha):
    rc, _, err = _cli(_rig(cmd, tmp_path, "--lead-mm", "5", "--alpha", alpha), capsys)
    _refused(rc, err, "--alpha", "1e-06", "0.5")
    assert not any(tmp_path.iterdir())          # refused before anything is written


def test_the_smallest_alpha_writes_finite_thresholds(tmp_path, capsys):
    rc, _, err = _cli(_rig("baseline", tmp_path, "--lead-mm", "5", "--alpha", "1e-6"),
                      capsys)
    assert rc == 0, err

    def refuse(token: str) -> float:
        raise AssertionError(f"not JSON: {token}")
    d = json.loads((tmp_path / "b.json").read_text(), parse_constant=refuse)
    thr = d["thresholds"]["40"]["thresholds"]
    assert thr and all(math.isfinite(v) and v > 0 for v in thr.values())


@pytest.mark.parametrize("lead", ["1e308", "1e-300", "0.05", "150", "inf"])
@pytest.mark.parametrize("cmd", COMMANDS)
def test_a_lead_outside_a_ball_screws_is_refused(tmp_path, capsys, cmd, lead):
    rc, _, err = _cli(_rig(cmd, tmp_path, "--lead-mm", lead), capsys)
    _refused(rc, err, "--lead-mm", "0.1 to 100 mm")
    assert not any(tmp_path.iterdir())


def test_the_lead_range_is_in_the_help(capsys):
    with pytest.raises(SystemExit):
        main(["rig", "baseline", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "0.1 to 100" in text and "1e-06" in text


@pytest.mark.parametrize("sizes", ["1e308", "4,51", "inf", "nan", "-1"])
def test_inject_refuses_a_size_beyond_a_physical_fault(tmp_path, capsys, sizes):
    rc, out, err = _cli(_rig("inject", tmp_path, "--lead-mm", "5", "--sizes", sizes), capsys)
    _refused(rc, err, "--sizes", f"at most {SIZE_MAX:g}")
    assert "inf %" not in out


def test_inject_takes_the_largest_size(tmp_path, capsys):
    rc, _, err = _cli(_rig("inject", tmp_path, "--lead-mm", "5", "--kinds", "friction",
                           "--sizes", f"{SIZE_MAX:g}"), capsys)
    assert rc == 0, err
    cell = json.loads((tmp_path / "inj" / "inject.json").read_text())["loads"]["40"]
    assert cell["kinds"]["friction"][f"{SIZE_MAX:g}"]["flagged"] == 10
    assert "RuntimeWarning" not in err


def test_the_size_bound_is_in_the_help(capsys):
    with pytest.raises(SystemExit):
        main(["rig", "inject", "--help"])
    assert f"at most {SIZE_MAX:g}" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("seed", ["-1", "4294967296"])
def test_train_refuses_a_seed_out_of_range(tmp_path, capsys, seed):
    rc, _, err = _cli(_rig("train", tmp_path, "--lead-mm", "5", "--seed", seed), capsys)
    _refused(rc, err, "--seed", "4294967295")
    assert not (tmp_path / "m.skops").exists()


@pytest.mark.parametrize("seed", [-1, 2 ** 32])
def test_a_seed_out_of_range_is_refused_before_any_work(seed):
    """A namespace built in code, not parsed, is checked too (`rig._check`)."""
    args = argparse.Namespace(rig_command="train", lead_mm=5.0, alpha=0.05, seed=seed,
                              folds=5)
    with pytest.raises(BenchError, match=r"--seed must be from 0 to 4294967295"):
        R._check(args)


def test_classify_says_a_directory_is_not_a_model(tmp_path, capsys):
    rc, _, err = _cli(["rig", "classify", tmp_path, SAMPLE / HEALTHY], capsys)
    _refused(rc, err, str(tmp_path), "a directory, not a model")


def test_classify_names_a_missing_model(tmp_path, capsys):
    rc, _, err = _cli(["rig", "classify", tmp_path / "none.skops", SAMPLE / HEALTHY], capsys)
    _refused(rc, err, "no such model")
