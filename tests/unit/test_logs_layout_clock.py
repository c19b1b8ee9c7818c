"""A log is decoded by its own clock and only when it is this node's layout: another
CANopen device's frames on the node's COB-IDs are refused beyond a small share (and
counted, emptied and said below it), and the SYNC period comes from the log (its SDO
0x1006, else its SYNC time stamps) with a warning when the two disagree."""

from __future__ import annotations

import can
import numpy as np
import pytest
from log_frames import F, run, write_log

from bench import BenchError
from bench.bus.logs import MISFIT_SHARE, trace_from_log
from bench.cli import main
from bench.signals.integrity import integrity


def foreign(n: int = 300) -> list[can.Message]:
    """A CiA 402 drive at node 0x10 under its own master: SYNC, TPDO1 = status word (2
    bytes), TPDO2 = status word + position (6), TPDO3 = position + velocity (8), RPDO1 =
    control word (2), on the bench node's COB-IDs."""
    out = []
    rng = np.random.default_rng(3)
    for k in range(n):
        t = 1000.0 + k * 1e-3
        pos = int(rng.integers(-2**31, 2**31 - 1))
        for cid, data, dt in ((0x080, bytes([k % 240 + 1]), 0.0),
                              (0x190, (0x0237).to_bytes(2, "little"), 1e-4),
                              (0x290, (0x0237).to_bytes(2, "little")
                               + pos.to_bytes(4, "little", signed=True), 1.1e-4),
                              (0x390, pos.to_bytes(4, "little", signed=True)
                               + int(rng.integers(0, 2**31)).to_bytes(4, "little"), 1.2e-4),
                              (0x210, (0x000F).to_bytes(2, "little"), 3e-4)):
            out.append(can.Message(timestamp=round(t + dt, 6), arbitration_id=cid, data=data,
                                   is_extended_id=False))
    return out


def test_another_devices_log_on_the_same_cob_ids_is_refused(tmp_path, capsys):
    """It was decoded with 6,000 bad frames and graded by bench usage as 65.7 M screw
    revolutions; fleet ingest stored it."""
    path = tmp_path / "drive.log"
    write_log(str(path), foreign())
    with pytest.raises(BenchError, match="not this node's layout: 600 of the 1200 frames "
                                         "on node 0x10's PDO and set-point ids do not fit"):
        trace_from_log(path)
    for argv in (["decode", str(path)], ["usage", str(path)],
                 ["hums", "report", str(path), "--out", str(tmp_path / "r")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert "not this node's layout" in err and len(err.splitlines()) == 1, err
    assert main(["fleet", "ingest", str(path), "--db", str(tmp_path / "f.duckdb"),
                 "--workers", "1"]) == 0
    out = capsys.readouterr()
    assert "0 runs stored, 1 failed" in out.out and "not this node's layout" in out.err


def test_a_few_damaged_frames_are_counted_emptied_and_said(tmp_path):
    seq = run(200)
    bad = [m for m in seq if m.arbitration_id == F.cob["ECU_Setpoint"]][:3]
    for m in bad:
        m.data = bytearray(bytes(m.data)[:7] + b"\x09")          # mode 9: no mode
    rpdo = [m for m in seq if m.arbitration_id == F.cob["EMA_RPDO1"]][10]
    rpdo.data = bytearray(b"\x01\x02")                           # 2 bytes: no layout
    rpdo.dlc = 2
    path = tmp_path / "run.log"
    write_log(str(path), seq)
    tr = trace_from_log(path)
    assert tr.meta["misfit_frames"] == {"ECU_Setpoint": 3, "EMA_RPDO1": 1}
    assert 4 <= MISFIT_SHARE * tr.meta["row_id_frames"]
    assert np.isnan(tr["mode"][:3]).all() and np.isnan(tr["setpoint_position_m"][:3]).all()
    assert np.isfinite(tr["mode"][3:]).all()
    assert any("4 frames not fitting the DBC's layout" in w for w in integrity(tr.meta))


def test_the_period_is_the_logs_own_sync_time_stamps(tmp_path, capsys):
    """A log whose SYNCs come every 1 s was decoded as 1 ms periods with no warning."""
    seq = run(30)
    for m in seq:
        m.timestamp = round(1000.0 + (m.timestamp - 1000.0) * 1000.0, 6)
    path = tmp_path / "slow.log"
    write_log(str(path), seq)
    tr = trace_from_log(path)
    assert tr.meta["period_s"] == 1.0 and tr.meta["clock"]["source"] == "SYNC time stamps"
    assert tr.t[-1] == pytest.approx(29.0)
    assert not integrity(tr.meta)
    assert main(["decode", str(path), "--period", "0.001"]) == 0
    assert "the SYNC time stamps are 1000 ms apart but --period gives a period of 1 ms" \
        in capsys.readouterr().out


def _sdo_period(us: int, t: float) -> list[can.Message]:
    """The ECU reading 0x1006 (communication cycle period, us) by an expedited upload."""
    return [can.Message(timestamp=t, arbitration_id=F.sdo_rx, is_extended_id=False,
                        data=bytes([0x40, 0x06, 0x10, 0, 0, 0, 0, 0])),
            can.Message(timestamp=t + 1e-4, arbitration_id=F.sdo_tx, is_extended_id=False,
                        data=bytes([0x43, 0x06, 0x10, 0]) + us.to_bytes(4, "little"))]


def test_the_logs_sdo_period_wins_and_a_disagreeing_clock_is_said(tmp_path):
    seq = run(30)
    path = tmp_path / "run.log"
    write_log(str(path), _sdo_period(1000, 998.0) + seq)
    tr = trace_from_log(path)
    assert tr.meta["clock"]["source"] == "SDO 0x1006" and "warning" not in tr.meta["clock"]
    write_log(str(path), _sdo_period(2000, 998.0) + seq)
    tr = trace_from_log(path)
    assert tr.meta["period_s"] == pytest.approx(2e-3)
    assert integrity(tr.meta)[0] == ("the SYNC time stamps are 1 ms apart but the log's SDO "
                                     "0x1006 gives a period of 2 ms: the table uses the log's "
                                     "SDO 0x1006's (give --period to choose)")
