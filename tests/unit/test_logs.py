"""candump logs: the tolerant reader agrees with python-can's writer/reader on good lines,
reports bad lines with their numbers, and the SDO tracker recovers transferred values."""

from __future__ import annotations

import io

import can
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.bus.logs import SdoTracker, parse_line, read_log, trace_from_messages
from ema_contract.frames import Frames

frames_st = st.builds(
    lambda ext, ident, data, ts, rtr: can.Message(
        timestamp=ts, arbitration_id=ident & (0x1FFFFFFF if ext else 0x7FF), is_extended_id=ext,
        is_remote_frame=rtr, dlc=len(data) if not rtr else min(len(data), 8),
        data=None if rtr else data),
    st.booleans(), st.integers(0, 0x1FFFFFFF), st.binary(max_size=8),
    st.floats(0, 2e9, allow_nan=False).map(lambda x: round(x, 6)), st.booleans())


@settings(max_examples=200, deadline=None)
@given(msgs=st.lists(frames_st, min_size=1, max_size=5))
def test_reader_agrees_with_python_can(msgs):
    buf = io.StringIO()
    w = can.CanutilsLogWriter(buf)
    for m in msgs:
        w.on_message_received(m)
    text = buf.getvalue()
    ref = list(can.CanutilsLogReader(io.StringIO(text)))
    ours = [parse_line(line) for line in text.splitlines()]
    assert len(ours) == len(ref)
    for a, b in zip(ours, ref, strict=True):
        assert a.equals(b, timestamp_delta=1e-6, check_channel=True, check_direction=True)


def test_bad_lines_are_reported_with_numbers_and_the_rest_kept(tmp_path):
    log = tmp_path / "bad.log"
    log.write_text("\n".join([
        "(1.000000) vcan0 080#01 T",          # 1 ok
        "(1.000100) vcan0 190#E80300004",     # 2 odd digits: truncated data
        "garbage line",                       # 3
        "(1.0002",                            # 4 truncated timestamp
        "(1.000300) vcan0 FFF#00",            # 5 standard id above 0x7FF
        "(1.000400) vcan0 290#00112233445566778899",   # 6 ten bytes
        "",                                   # blank: ignored
        "(1.000500) vcan0 390#0011223344 R",  # 8 ok
        "(1.000600) vcan0 210#R",             # 9 ok: remote frame
    ]) + "\n(1.000700) vcan0 080#0")          # 10 truncated last line, no newline
    issues = []
    msgs = list(read_log(log, issues))
    assert [m.arbitration_id for m in msgs] == [0x80, 0x390, 0x210]
    assert [i.line for i in issues] == [2, 3, 4, 5, 6, 10]
    assert "truncated" in issues[0].reason and "line 2" in str(issues[0])


def test_an_extended_id_above_29_bits_is_a_bad_line_but_an_error_frame_is_kept():
    """An 8-digit id with bits above 0x1FFFFFFF (other than candump's error flag) was read
    as an extended frame with a 32-bit id, and `bench replay` played it."""
    for line in ("(1.0) vcan0 80000000#00", "(1.0) vcan0 5FFFFFFF#00",
                 "(1.0) vcan0 40000123#R"):
        with pytest.raises(ValueError, match="extended id .* above 0x1FFFFFFF"):
            parse_line(line)
    assert parse_line("(1.0) vcan0 1FFFFFFF#00").arbitration_id == 0x1FFFFFFF
    assert parse_line("(1.0) vcan0 20000004#0000080000000000").is_error_frame


@settings(max_examples=100, deadline=None)
@given(st.text(alphabet="()0123456789.#ABCDEFR vcan\t", max_size=40))
def test_parse_line_never_raises_anything_but_valueerror(text):
    try:
        parse_line(text)
    except ValueError:
        pass


def _sdo(cob, *data):
    return can.Message(arbitration_id=cob, data=bytes(data), is_extended_id=False)


def test_sdo_tracker_expedited_and_segmented():
    t = SdoTracker(0x610, 0x590)
    # expedited download of 0x1006 = 2000, confirmed
    t.feed(_sdo(0x610, 0x23, 0x06, 0x10, 0x00, 0xD0, 0x07, 0, 0))
    t.feed(_sdo(0x590, 0x60, 0x06, 0x10, 0x00, 0, 0, 0, 0))
    assert t.values[(0x1006, 0)] == bytes([0xD0, 0x07, 0, 0])
    # segmented upload of an 8-byte value
    t.feed(_sdo(0x610, 0x40, 0x00, 0x20, 0x01, 0, 0, 0, 0))
    t.feed(_sdo(0x590, 0x41, 0x00, 0x20, 0x01, 8, 0, 0, 0))
    t.feed(_sdo(0x610, 0x60, 0, 0, 0, 0, 0, 0, 0))
    t.feed(_sdo(0x590, 0x00, 1, 2, 3, 4, 5, 6, 7))
    t.feed(_sdo(0x610, 0x70, 0, 0, 0, 0, 0, 0, 0))
    t.feed(_sdo(0x590, 0x1D, 8, 0, 0, 0, 0, 0, 0))
    assert t.values[(0x2000, 1)] == bytes([1, 2, 3, 4, 5, 6, 7, 8])
    # an aborted download leaves nothing
    t.feed(_sdo(0x610, 0x2F, 0x00, 0x22, 0x01, 1, 0, 0, 0))
    t.feed(_sdo(0x590, 0x80, 0x00, 0x22, 0x01, 0x22, 0, 0, 8))
    assert (0x2200, 1) not in t.values


def test_frames_of_the_older_shorter_layout_keep_the_signals_they_carry():
    """EMA_TPDO3 was 6 bytes before the load cell: logs of that layout still give LVDT and
    temperature (load left empty), counted as short frames, not dropped as bad ones."""
    f = Frames()
    seq = []
    for k in range(3):
        seq.append(f.encode("SYNC", {"SYNC_Counter": k + 1}))
        full = f.encode("EMA_TPDO3", {"LvdtPosition": k * 1e-3, "WindingTemperature": 300,
                                      "LoadForce": 0.0})
        full.data = full.data[:6]
        full.dlc = 6
        seq.append(full)
    tr = trace_from_messages(seq)
    assert tr.meta["short_frames"] == 3 and tr.meta["bad_frames"] == 0
    assert list(tr["position_m"]) == pytest.approx([0, 1e-3, 2e-3])
    assert list(tr["winding_temperature_k"]) == pytest.approx([300, 300, 300])
    assert np.isnan(tr["load_force_n"]).all()


def test_trace_rows_follow_sync_and_keep_time_across_lost_syncs():
    f = Frames()
    seq = []
    for k, counter in enumerate((1, 2, 4, 5)):       # SYNC 3 lost
        seq.append(f.encode("SYNC", {"SYNC_Counter": counter}))
        seq.append(f.encode("EMA_TPDO3", {"LvdtPosition": k * 1e-3, "WindingTemperature": 300,
                                             "LoadForce": 10.0 * k}))
        seq.append(f.encode("EMA_RPDO1", {"CurrentDemand": float(k), "ControlWord": 1}))
    seq.insert(4, can.Message(arbitration_id=0x390, data=b"\x00", is_extended_id=False))
    tr = trace_from_messages(seq)
    assert len(tr) == 5 and tr.meta["sync_gaps"] == 1 and tr.meta["bad_frames"] == 1
    assert list(tr["position_m"][[0, 1, 3, 4]]) == pytest.approx([0, 1e-3, 2e-3, 3e-3])
    assert list(tr["load_force_n"][[0, 1, 3, 4]]) == pytest.approx([0, 10, 20, 30])
    assert tr["current_demand_a"][2] != tr["current_demand_a"][2]   # NaN row
    assert tr["t_s"][4] == pytest.approx(4e-3)
