"""Fuzz test of the log reader: `parse_line`, `read_log` and
`trace_from_messages` on generated lines and generated frame sequences never raise
anything but their documented errors (ValueError from `parse_line`, nothing from the
other two on a readable file but a BenchError for SYNC counters claiming more lost
SYNCs than the log can have), keep their memory bounded and are deterministic
(hypothesis with ``derandomize=True``). The whole module runs in well under 15 s."""

from __future__ import annotations

import random
import tracemalloc

import can
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from log_frames import F, run

from bench import BenchError
from bench.bus.logs import LogIssues, parse_line, read_log, trace_from_messages

FUZZ = settings(derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow])

HEX = "0123456789ABCDEFabcdef"
timestamps = st.one_of(st.from_regex(r"\A[0-9]{1,12}(\.[0-9]{0,8})?\Z"),
                       st.text("0123456789.-e+", max_size=10))
frame_lines = st.builds(
    lambda ts, close, ch, ident, sep, data, d: f"({ts}{close} {ch} {ident}{sep}{data}{d}",
    timestamps, st.sampled_from([")", ")", ""]), st.sampled_from(["vcan0", "can0", ""]),
    st.text(HEX, max_size=9), st.sampled_from(["#", "#", "##1", "##3", "##", "#R", ""]),
    st.one_of(st.text(HEX, max_size=20), st.sampled_from(["R", "R8", "R9", "R15", "R1x"]),
              st.text(HEX, min_size=128, max_size=130)),
    st.sampled_from(["", " R", " T", " X", "  ", "\t"]))
any_line = st.one_of(frame_lines, st.text(max_size=60),
                     st.binary(max_size=40).map(lambda b: b.decode("latin-1")))


@FUZZ
@given(any_line)
def test_parse_line_raises_only_valueerror(text):
    try:
        msg = parse_line(text)
    except ValueError:
        return
    assert isinstance(msg, can.Message) and len(msg.data) <= 64


@FUZZ
@given(st.lists(any_line, max_size=30), st.sampled_from(["\n", "\r\n"]))
def test_read_log_reads_every_line_as_a_frame_or_an_issue(tmp_path_factory, lines, end):
    path = tmp_path_factory.mktemp("fuzz") / "f.log"
    path.write_bytes(end.join(lines).encode("utf-8", "surrogatepass"))
    issues = LogIssues(5)
    frames = list(read_log(path, issues))
    with path.open("r", errors="replace", newline="") as fh:
        non_blank = sum(1 for s in fh if s.strip())
    assert len(frames) + len(issues) == non_blank
    assert len(list(issues)) == min(5, len(issues))


# -- frame sequences -----------------------------------------------------------------------
IDS = [F.cob[n] for n in ("SYNC", "NMT", "EMA_EMCY", "ECU_Setpoint", "EMA_TPDO1",
                          "EMA_TPDO2", "EMA_TPDO3", "EMA_RPDO1", "EMA_Heartbeat")]
IDS += [F.sdo_rx, F.sdo_tx, 0x123]

edits = st.lists(st.tuples(
    st.sampled_from(["drop", "dup", "move", "corrupt", "insert", "retime", "resize"]),
    st.integers(0, 10_000), st.integers(0, 10_000), st.binary(max_size=9),
    st.floats(-2.0, 2.0)), max_size=12)


def damaged(n: int, ops: list) -> list[can.Message]:
    """An intact run of n SYNC periods with the edits `ops` applied."""
    seq = run(n)
    for op, i, j, data, dt in ops:
        i %= len(seq) + (op == "insert")
        if op == "insert":
            seq.insert(i, can.Message(timestamp=seq[min(i, len(seq) - 1)].timestamp + dt,
                                      arbitration_id=IDS[j % len(IDS)], data=data[:8],
                                      is_extended_id=False))
            continue
        if not seq:
            break
        m = seq[i]
        if op == "drop":
            seq.pop(i)
        elif op == "dup":
            seq.insert(i + 1, _copy(m, m.timestamp + (dt if j % 2 else 0.0)))
        elif op == "move":
            seq.insert(j % len(seq), seq.pop(i))
        elif op == "corrupt":
            m.data = bytearray(data[:len(m.data)].ljust(len(m.data), b"\0"))
        elif op == "retime":
            m.timestamp += dt
        elif op == "resize":
            m.data = bytearray(data[:8])
            m.dlc = len(m.data)
    return seq


def _copy(m: can.Message, ts: float) -> can.Message:
    return can.Message(timestamp=ts, arbitration_id=m.arbitration_id, data=bytes(m.data),
                       is_extended_id=m.is_extended_id, is_rx=m.is_rx)


def _table(tr) -> dict[str, np.ndarray]:
    return {k: v for k, v in tr.columns.items()}


@FUZZ
@given(st.integers(1, 30), edits)
def test_any_damaged_sequence_decodes_and_every_line_twice_changes_nothing(n, ops):
    seq = damaged(n, ops)
    twice_seq = [c for msg in seq for c in (msg, _copy(msg, msg.timestamp))]
    try:
        tr = trace_from_messages(seq)
    except BenchError as exc:          # corrupted SYNC counters claiming > 1000 lost
        assert str(exc).startswith("the SYNC counters make no sense: ")
        with pytest.raises(BenchError, match="the SYNC counters make no sense"):
            trace_from_messages(twice_seq)
        return
    syncs = sum(1 for m in seq if m.arbitration_id == F.cob["SYNC"])
    assert len(tr) <= 240 * syncs                       # rows bounded by the SYNCs read
    m = tr.meta
    assert m["frames"] == len(seq)
    assert all(m[k] >= 0 for k in ("sync_gaps", "duplicate_frames", "replaced_frames",
                                   "out_of_order", "bad_frames", "sync_recovered"))
    assert all(0 <= v <= len(tr) for v in m["missing_frames"].values())
    twice = trace_from_messages(twice_seq)
    assert len(twice) == len(tr)
    for k, v in _table(tr).items():
        np.testing.assert_array_equal(twice[k], v, err_msg=k)


@FUZZ
@given(st.integers(2, 40), st.integers(0, 10_000))
def test_a_lost_sync_line_changes_only_its_bus_time(n, k):
    intact = trace_from_messages(run(n))
    seq = run(n)
    syncs = [i for i, m in enumerate(seq) if m.arbitration_id == F.cob["SYNC"]]
    lost = 1 + k % (n - 1)                  # not the first SYNC: it has no row before it
    del seq[syncs[lost]]
    tr = trace_from_messages(seq)
    assert tr.meta["sync_gaps"] == tr.meta["sync_recovered"] == 1
    for c, v in _table(intact).items():
        if c == "bus_time_s":
            assert np.isnan(tr[c][lost])
            np.testing.assert_allclose(np.delete(tr[c], lost), np.delete(v, lost))
        else:
            np.testing.assert_array_equal(tr[c], v, err_msg=c)


def test_decoding_memory_is_bounded_by_the_rows_not_the_frames():
    """20,000 random frames of the bus's ids (SYNCs counting up), streamed: the decoder
    keeps the rows (one per SYNC, 8 bytes a signal) and bounded lists, not the frames
    (which would take ~4.6 MB as can.Message objects)."""
    r = random.Random(7)

    def frames():
        counter = 0
        for k in range(20_000):
            cid = IDS[r.randrange(len(IDS))]
            if cid == F.cob["SYNC"]:
                counter = counter % 240 + 1
                data = bytes([counter])
            else:
                data = bytes(r.randrange(256) for _ in range(r.choice((1, 6, 8))))
            yield can.Message(timestamp=1000 + k * 1e-4, arbitration_id=cid, data=data,
                              is_extended_id=False)
    trace_from_messages([])                       # the DBC and EDS, parsed once, not counted
    tracemalloc.start()
    try:
        tr = trace_from_messages(frames())
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert tr.meta["frames"] == 20_000 and 1000 < len(tr) < 2500
    assert peak < 2_000_000, f"{peak / 1e6:.1f} MB"
