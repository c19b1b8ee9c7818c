"""Bus logs in every format python-can writes: one short lockstep run's frames,
written as candump .log by the ECU, then as .asc, .blf, .trc and .mf4 by python-can's
writers, decode to the same table and the same parameters (from the SDO traffic) as the
candump log; bus time within the format's time-stamp resolution. A damaged or unknown
file is a one-line error."""

from __future__ import annotations

import threading

import can
import numpy as np
import pytest

from bench import BenchError
from bench.bus.logs import load_trace, read_frames, read_log, trace_from_log
from bench.bus.logwrite import LOG_FORMATS, open_writer
from bench.cli import main
from bench.ecu import run_over_bus
from bench.profiles.catalog import make_profile
from ema_contract.states import Pace
from ema_contract.transport import close_bus
from plant_rt.node import PlantNode
from plant_rt.params import PlantParams

OTHER = [s for s in LOG_FORMATS if s != ".log"]
# bus time: candump has microseconds; ASC and TRC write microseconds relative to the
# file's start (measured: within 0.15 us and 0.24 us of candump), BLF and MF4 agree exactly
RESOLUTION_S = 1e-6


@pytest.fixture(scope="module")
def candump(tmp_path_factory):
    """A 0.1 s lockstep run (noise on, a parameter set) against a plant node on a virtual
    bus, logged by the ECU as candump."""
    chan = "log-formats"          # fixed: a random name ending in digits made it flaky
    nbus = can.Bus(interface="virtual", channel=chan)
    node = PlantNode(nbus, PlantParams(), pace=Pace.SYNC)
    th = threading.Thread(target=node.run, daemon=True)
    th.start()
    log = tmp_path_factory.mktemp("fmt") / "run.log"
    try:
        run_over_bus(make_profile("sine", duration_s=0.1), pace="sync",
                     settings={"interface": "virtual", "channel": chan},
                     values={"sensors.noise": True, "effects.backlash_m": 20e-6},
                     start_plant=False, log_path=log)
    finally:
        node.stop()
        th.join(2.0)
        close_bus(nbus)
    return log


def write_as(candump, suffix: str):
    out = candump.with_name(f"run{suffix}")
    if not out.exists():
        writer = open_writer(out)
        for msg in read_log(candump):
            writer.on_message_received(msg)
        writer.stop()
    return out


@pytest.mark.parametrize("suffix", OTHER)
def test_each_format_decodes_to_the_candump_table(candump, suffix):
    ref = trace_from_log(candump)
    path = write_as(candump, suffix)
    n = sum(1 for _ in read_frames(path))
    dec = trace_from_log(path)
    assert n == ref.meta["frames"] == dec.meta["frames"]
    assert len(dec) == len(ref) == 100 and sorted(dec.columns) == sorted(ref.columns)
    for col in ref.columns:
        if col == "bus_time_s":
            np.testing.assert_allclose(dec[col], ref[col], rtol=0, atol=RESOLUTION_S)
        else:
            np.testing.assert_array_equal(dec[col], ref[col], err_msg=col)
    params = PlantParams.from_dict(dec.meta["params"])     # the SDO traffic, read back
    assert params.diff(PlantParams.from_dict(ref.meta["params"])) == {}
    assert params.effects.backlash_m == 20e-6 and params.sensors.noise
    for key in ("sync_gaps", "duplicate_frames", "out_of_order", "bad_frames", "issue_count",
                "missing_frames", "runs"):
        assert dec.meta[key] == ref.meta[key], key
    assert load_trace(path).meta["source"] == str(path)


def one_line_error(capsys, *argv: str) -> str:
    rc = main(list(argv))
    out = capsys.readouterr()
    err = out.err.strip()
    assert rc != 0, out.out
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("suffix", [".blf", ".mf4"])
def test_a_damaged_file_is_a_one_line_error(candump, tmp_path, capsys, suffix):
    data = write_as(candump, suffix).read_bytes()
    bad = tmp_path / f"bad{suffix}"
    bad.write_bytes(data[:64] + bytes(range(256)) * 8 + data[64 + 2048:])
    err = one_line_error(capsys, "decode", str(bad))
    assert str(bad) in err and LOG_FORMATS[suffix] in err and "python-can" in err, err
    with pytest.raises(BenchError, match="cannot read this"):
        list(read_frames(bad))


def test_an_unknown_format_is_a_one_line_error(tmp_path, capsys):
    other = tmp_path / "run.xyz"
    other.write_text("(1.0) vcan0 080#01\n")
    err = one_line_error(capsys, "decode", str(other))
    assert "unknown log format '.xyz'" in err and ".blf" in err, err
    err = one_line_error(capsys, "log", str(tmp_path / "out.csv"), "--duration", "1")
    assert "unknown suffix '.csv'" in err and ".mf4" in err, err
    err = one_line_error(capsys, "log", str(tmp_path / "out.trc"), "--max-bytes", "1000")
    assert "--max-bytes" in err and ".trc" in err, err


def test_rotation_keeps_every_frame(candump, tmp_path):
    """`bench log --max-bytes`: python-can's SizedRotatingLogger; the files together hold
    every frame, each file a log of its own."""
    frames = list(read_log(candump))
    writer = open_writer(tmp_path / "rot.log", max_bytes=20_000)
    for msg in frames:
        writer.on_message_received(msg)
    writer.stop()
    files = sorted(tmp_path.glob("rot*.log"))
    assert len(files) >= 3
    got = [m for f in files for m in read_frames(f)]
    assert len(got) == len(frames)
    assert sorted(m.timestamp for m in got) == sorted(m.timestamp for m in frames)


@pytest.mark.parametrize("suffix", OTHER)
def test_a_channel_number_the_format_cannot_hold_loses_no_frame(tmp_path, suffix):
    """A bus named with a large trailing number (a virtual bus ``bench-624``): before the
    fix the MF4 writer raised OverflowError on the first frame and the log was lost."""
    out = tmp_path / f"chan{suffix}"
    writer = open_writer(out)
    sent = [can.Message(timestamp=1.0 + k * 1e-3, arbitration_id=0x80 + k, data=[k],
                        is_extended_id=False, channel="bench-624") for k in range(5)]
    for msg in sent:
        writer.on_message_received(msg)
    writer.stop()
    got = [m for m in read_frames(out)]
    assert [(m.arbitration_id, bytes(m.data)) for m in got] == \
        [(m.arbitration_id, bytes(m.data)) for m in sent]


@pytest.mark.parametrize("suffix", [".asc", ".trc", ".blf", ".mf4"])
def test_a_file_of_random_bytes_is_said_in_words(tmp_path, capsys, suffix):
    """Random bytes under a log's suffix: one line saying what is wrong with the file,
    not the reading library's exception class (UnicodeDecodeError, BLFParseError,
    MdfException)."""
    bad = tmp_path / f"bad{suffix}"
    bad.write_bytes(bytes(np.random.default_rng(7).integers(0, 256, 2000, dtype=np.uint8)))
    err = one_line_error(capsys, "decode", str(bad))
    assert str(bad) in err and LOG_FORMATS[suffix] in err, err
    assert "Error" not in err and "Exception" not in err, err
    if suffix in (".asc", ".trc"):
        assert "not a text file" in err, err


COMPRESS = {".gz": "gzip", ".xz": "lzma", ".bz2": "bz2"}


def compress_as(path, comp: str):
    import importlib
    import shutil
    out = path.with_name(path.name + comp)
    if not out.exists():
        with open(path, "rb") as src, importlib.import_module(COMPRESS[comp]).open(out, "wb") \
                as dst:
            shutil.copyfileobj(src, dst)
    return out


@pytest.mark.parametrize("comp", list(COMPRESS))
@pytest.mark.parametrize("suffix", list(LOG_FORMATS))
def test_a_compressed_log_decodes_to_the_table_of_the_plain_one(candump, suffix, comp):
    """`bench usage run.log.xz` said "unknown log format '.xz'": a log is often kept
    compressed (candump text shrinks 6x under gzip, 13x under xz)."""
    plain = candump if suffix == ".log" else write_as(candump, suffix)
    path = compress_as(plain, comp)
    ref, dec = load_trace(plain), load_trace(path)
    assert len(dec) == len(ref) == 100 and dec.meta["frames"] == ref.meta["frames"]
    for col in ref.columns:
        np.testing.assert_array_equal(dec[col], ref[col], err_msg=col)
    assert dec.meta["source"] == str(path)


@pytest.mark.parametrize("name", ["run.log", "run.blf"])
def test_a_truncated_compressed_log_is_a_one_line_error(candump, tmp_path, capsys, name):
    src = candump if name == "run.log" else write_as(candump, ".blf")
    data = compress_as(src, ".gz").read_bytes()
    cut = tmp_path / f"{name}.gz"
    cut.write_bytes(data[: len(data) // 2])
    err = one_line_error(capsys, "decode", str(cut))
    assert str(cut) in err and "cannot decompress" in err and ".gz file" in err, err
    not_gz = tmp_path / f"other{name}.xz"
    not_gz.write_bytes(src.read_bytes())
    err = one_line_error(capsys, "decode", str(not_gz))
    assert "cannot decompress" in err, err


def test_a_compressed_candump_log_replays_its_frames(candump):
    import argparse

    from bench.cli.replay import check_arguments, frames
    path = compress_as(candump, ".xz")
    args = argparse.Namespace(speed=0.0, max_gap=10.0, file=str(path))
    assert check_arguments(args) == path
    plain, issues = list(frames(candump, [])), []
    got = list(frames(path, issues))
    assert not issues and len(got) == len(plain) > 500
    assert all(a.equals(b) for a, b in zip(got, plain, strict=True))
