"""Decoding damaged frame sequences: missing frames counted per frame
kind, lost SYNCs found by the counter (and their frames kept in their own row when only
the SYNC line is gone), duplicates detected and dropped (one row per SYNC period), a
time-shuffled log sorted back, and no verdict-changing shift of a period's values."""

from __future__ import annotations

import random

import numpy as np
import pytest
from log_frames import T0, F, at, clone, run, where, write_log

from bench.bus.logs import trace_from_log, trace_from_messages

VALUE_COLUMNS = ("setpoint_position_m", "mode", "current_demand_a", "current_a",
                 "motor_speed_rad_s", "motor_angle_rad", "position_m", "load_force_n",
                 "status_word")


def assert_same_table(a, b, skip: tuple[str, ...] = ()) -> None:
    assert len(a) == len(b)
    for c in VALUE_COLUMNS + ("t_s", "bus_time_s", "run"):
        if c in skip:
            continue
        np.testing.assert_array_equal(a[c], b[c], err_msg=c)


@pytest.fixture(scope="module")
def intact():
    return trace_from_messages(run())


def test_an_intact_sequence_has_nothing_to_report(intact):
    m = intact.meta
    assert len(intact) == 20 and m["runs"] == 1
    assert m["sync_gaps"] == 0 and m["duplicate_frames"] == 0 and m["out_of_order"] == 0
    assert m["sync_recovered"] == 0 and m["replaced_frames"] == 0
    assert m["missing_frames"] == {"ECU_Setpoint": 0, "EMA_TPDO1": 0, "EMA_TPDO2": 0,
                                   "EMA_TPDO3": 0, "EMA_RPDO1": 0}
    assert np.isfinite(np.column_stack([intact[c] for c in VALUE_COLUMNS])).all()


def test_one_missing_tpdo1_is_counted_for_its_frame_kind(intact):
    seq = run()
    del seq[where(seq, 7, "EMA_TPDO1")]
    tr = trace_from_messages(seq)
    assert len(tr) == 20
    assert tr.meta["missing_frames"]["EMA_TPDO1"] == 1
    assert sum(tr.meta["missing_frames"].values()) == 1
    assert np.isnan(tr["current_a"][7]) and np.isnan(tr["status_word"][7])
    assert_same_table(tr, intact, skip=("current_a", "status_word"))


def test_a_lost_sync_line_keeps_its_frames_in_their_own_row(intact):
    """Only the SYNC line is gone: the counter says one SYNC is missing and the frames
    that followed it are that period's, not the previous period's (no shifted row)."""
    seq = run()
    del seq[where(seq, 7, "SYNC")]
    tr = trace_from_messages(seq)
    assert len(tr) == 20
    assert tr.meta["sync_gaps"] == 1 and tr.meta["sync_recovered"] == 1
    assert sum(tr.meta["missing_frames"].values()) == 0
    assert_same_table(tr, intact, skip=("bus_time_s",))
    assert np.isnan(tr["bus_time_s"][7])


def test_a_lost_period_leaves_one_empty_row(intact):
    seq = run()
    lo = where(seq, 7, "SYNC")
    del seq[lo:lo + 6]
    tr = trace_from_messages(seq)
    assert len(tr) == 20 and tr.meta["sync_gaps"] == 1 and tr.meta["sync_recovered"] == 0
    assert set(tr.meta["missing_frames"].values()) == {1}
    assert np.isnan(tr["current_a"][7]) and np.isnan(tr["position_m"][7])
    assert tr["current_a"][8] == intact["current_a"][8]


def test_every_line_twice_gives_the_intact_table(intact):
    seq = [copy for m in run() for copy in (m, at(clone(m), m.timestamp))]
    tr = trace_from_messages(seq)
    assert_same_table(tr, intact)
    assert tr.meta["duplicate_frames"] == len(seq) // 2
    assert tr.meta["runs"] == 1 and tr.meta["sync_gaps"] == 0


def test_the_same_frame_twice_in_one_period_is_a_duplicate(intact):
    seq = run()
    i = where(seq, 4, "EMA_TPDO2")
    seq.insert(i + 1, at(clone(seq[i]), seq[i].timestamp + 5e-6))
    j = where(seq, 9, "SYNC")
    seq.insert(j + 1, at(clone(seq[j]), seq[j].timestamp + 20e-6))   # repeated counter
    tr = trace_from_messages(seq)
    assert_same_table(tr, intact)
    assert tr.meta["duplicate_frames"] == 2 and tr.meta["sync_gaps"] == 0


def test_a_late_pdo_after_the_next_sync_does_not_hide_the_current_one(intact):
    """A TPDO of period 7 logged after SYNC 8 (a late frame of a real-time log): no SYNC
    is missing, so period 8 keeps its own TPDO1 and period 7 counts it missing."""
    seq = run()
    late = seq.pop(where(seq, 7, "EMA_TPDO1"))
    seq.insert(where(seq, 8, "ECU_Setpoint") + 1, late)
    tr = trace_from_messages(seq)
    assert tr["current_a"][8] == intact["current_a"][8]
    assert np.isnan(tr["current_a"][7])
    assert tr.meta["missing_frames"]["EMA_TPDO1"] == 1 and tr.meta["replaced_frames"] == 1
    assert tr.meta["sync_gaps"] == 0


def test_a_time_shuffled_log_is_sorted_back_by_timestamp(tmp_path, intact):
    good = tmp_path / "good.log"
    write_log(good, run())
    lines = good.read_text().splitlines()
    random.Random(4).shuffle(lines)
    shuffled = tmp_path / "shuffled.log"
    shuffled.write_text("\n".join(lines) + "\n")
    a, b = trace_from_log(good), trace_from_log(shuffled)
    assert a.meta["out_of_order"] == 0 and not a.meta["sorted_by_time"]
    assert b.meta["out_of_order"] >= 10 and b.meta["sorted_by_time"]
    assert_same_table(b, a)
    assert b.meta["sync_gaps"] == 0 and b.meta["duplicate_frames"] == 0


def test_local_disorder_of_a_live_log_is_not_reordered(tmp_path, intact):
    """The ECU stamps its own frames when it logs them and received ones at the hub, so a
    TPDO may carry a time a little before the set-point logged ahead of it, and a plant
    heartbeat may reach the log 0.17 s late: that is not a damaged log (no count, no
    sorting)."""
    seq = run()
    for k in range(20):
        m = seq[where(seq, k, "EMA_TPDO1")]
        m.timestamp = round(m.timestamp - 80e-6, 6)      # before ECU_Setpoint's stamp
    path = tmp_path / "live.log"
    write_log(path, seq)
    lines = path.read_text().splitlines()
    hb = f"({T0 - 0.17:.6f}) vcan0 {F.cob['EMA_Heartbeat']:03X}#7F R"   # logged 0.17 s late
    path.write_text("\n".join(lines[:30] + [hb] + lines[30:]) + "\n")
    tr = trace_from_log(path)
    assert tr.meta["out_of_order"] == 0 and not tr.meta["sorted_by_time"]
    assert_same_table(tr, intact, skip=("bus_time_s",))


def test_the_last_sync_line_lost_is_found_by_the_new_set_point(intact):
    """No later SYNC counter tells that the last SYNC line is missing: the frames led by
    a new ECU set-point (sent right after each SYNC) are that period's."""
    seq = run()
    del seq[where(seq, 19, "SYNC")]
    tr = trace_from_messages(seq)
    assert tr.meta["sync_gaps"] == tr.meta["sync_recovered"] == 1
    assert_same_table(tr, intact, skip=("bus_time_s",))


def test_syncs_without_counter_and_a_lost_sync_line(intact):
    seq = run()
    for m in seq:
        if m.arbitration_id == F.cob["SYNC"]:
            m.data = bytearray()
            m.dlc = 0
    del seq[where(seq, 7, "SYNC")]
    tr = trace_from_messages(seq)
    assert tr.meta["sync_gaps"] == tr.meta["sync_recovered"] == 1
    assert_same_table(tr, intact, skip=("bus_time_s",))
