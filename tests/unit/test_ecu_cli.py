"""`bench run`'s input checks: every bad flag is a one-line error
before anything starts (no hub, no plant, no bus), for every profile."""

from __future__ import annotations

import inspect
import math

import pytest

from bench import BenchError
from bench.cli import main
from bench.profiles.catalog import PROFILES, make_profile

# keywords that must be > 0 (a frequency, a count of cycles, a length of time)
POSITIVE = ("frequency_hz", "f0_hz", "f1_hz", "cycles", "duration_s")


@pytest.fixture
def nothing_starts(monkeypatch, tmp_path):
    """Fail loudly if `bench run` gets as far as starting a hub or opening a bus."""
    import bench.bus
    import bench.bus.procs

    def started(*a, **kw):
        raise AssertionError("a hub, a plant or a bus was started")

    monkeypatch.setenv("BENCH_STATE_DIR", str(tmp_path / "state"))
    for var in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_CONFIG"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setattr(bench.bus.procs, "start_hub", started)
    monkeypatch.setattr(bench.bus.procs, "start_plant", started)
    monkeypatch.setattr(bench.bus, "connect", started)


def one_line_error(capsys, *argv: str) -> str:
    rc = main(["run", *argv])
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    assert "Traceback" not in err and "Error:" not in err.split(":", 1)[1], err
    return err


def numeric_keywords():
    for name, factory in PROFILES.items():
        for kw, p in inspect.signature(factory).parameters.items():
            if isinstance(p.default, (int, float)) or p.default is None:
                yield name, kw


@pytest.mark.parametrize("name, kw", list(numeric_keywords()))
def test_every_numeric_profile_parameter_refuses_non_finite_and_out_of_domain(name, kw):
    bad = [math.nan, math.inf, -math.inf]
    if kw in POSITIVE:
        bad += [0.0, -1.0]
    for v in bad:
        with pytest.raises(BenchError, match=kw):
            make_profile(name, **{kw: v})


def test_frequency_zero_is_a_one_line_error(nothing_starts, capsys):
    """Unfixed: ZeroDivisionError (cycles / frequency_hz), exit 1."""
    err = one_line_error(capsys, "sine", "--frequency-hz", "0")
    assert "--frequency-hz 0" in err and "above 0" in err
    err = one_line_error(capsys, "velocity-cosine", "--frequency-hz", "-2")
    assert "--frequency-hz -2" in err


def test_a_duration_beyond_memory_is_refused_before_anything_starts(nothing_starts, capsys):
    """Unfixed: a hub and a plant were started, then MemoryError (1e5 s took 9.5 GB)."""
    err = one_line_error(capsys, "sine", "--pace", "sync", "--duration", "1e12")
    assert "--duration" in err and "memory" in err and " s " in err


def test_a_duration_below_one_period_is_refused_before_anything_starts(nothing_starts,
                                                                       capsys):
    err = one_line_error(capsys, "step", "--duration", "1e-6")
    assert "SYNC period" in err


@pytest.mark.parametrize("flag", ["--log", "--save"])
def test_unwritable_output_paths_are_refused_first(nothing_starts, capsys, tmp_path, flag):
    """Unfixed: --save was tried only after the whole run (FileNotFoundError), --log
    /dev/full killed the ECU's receive thread."""
    what = "log" if flag == "--log" else "trace"
    ext = ".log" if flag == "--log" else ".npz"
    folder = tmp_path / f"folder{ext}"
    folder.mkdir()
    for path, why in [(tmp_path / "missing" / f"x{ext}", "No such file or directory"),
                      (folder, "Is a directory"),
                      ("/dev/full", "No space left on device")]:
        if flag == "--save" and path == "/dev/full":
            continue      # no table suffix: refused by format (next test)
        err = one_line_error(capsys, "step", flag, str(path))
        assert f"cannot write the {what} {path}" in err and why in err, err
    assert not (tmp_path / "missing").exists()


def test_save_format_is_checked_first(nothing_starts, capsys, tmp_path):
    err = one_line_error(capsys, "step", "--save", str(tmp_path / "x.xlsx"))
    assert "unknown table format" in err


def test_the_output_probe_leaves_existing_files_as_they_were(nothing_starts, capsys,
                                                             tmp_path, monkeypatch):
    """The probe appends nothing and creates nothing that the run would not."""
    from bench.signals.trace import probe_output
    old = tmp_path / "old.log"
    old.write_text("keep me\n")
    probe_output(old, "log")
    assert old.read_text() == "keep me\n"
    new = tmp_path / "new.npz"
    probe_output(new, "trace")
    assert not new.exists()
