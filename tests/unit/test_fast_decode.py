"""The fast log path gives what the per-frame path gives, to the bit: the
vectorised DBC codec (`ema_contract.frames.PayloadCodec`) against cantools, the candump
line parser `fast_frame` against `parse_line`, the decoded traces of fixture logs (clean,
damaged, a synthetic fleet log) against the old path (every line through `parse_line`,
every frame decoded by cantools as it comes, the rows built from those values), and
`write_candump`'s bytes against the old frame-by-frame writer."""

from __future__ import annotations

import math
import random

import cantools
import numpy as np
import pytest
from log_frames import F, run, where, write_log

from bench.bus.logread import fast_frame, parse_line
from bench.bus.logs import LogIssues, _codec, read_log, trace_from_log
from bench.bus.rows import COLUMNS, ROW_FRAMES, SIGNAL_COLUMNS, TWO_PI, RowAssembler
from bench.fleet.synth import _stamp_chars, write_candump
from bench.signals.trace import Trace
from ema_contract.frames import PayloadCodec
from ema_contract.states import ControlWord, NMTCommand, StatusWord

OTHER_DBC = '''VERSION ""
NS_ :
BS_:
BU_: A B
BO_ 100 BE: 8 A
 SG_ S1 : 7|12@0- (0.5,-3) [-1000|1000] "" B
 SG_ S2 : 11|20@0+ (3,7) [7|3000000] "" B
 SG_ S3 : 39|32@0- (1,0) [-1000|1000] "" B
BO_ 101 LEF: 7 A
 SG_ F1 : 0|32@1- (2.5,1) [-1000|1000] "" B
 SG_ F2 : 32|16@1+ (1,0) [0|65535] "" B
 SG_ F3 : 48|8@1- (1,-5) [-100|100] "" B
BO_ 102 BEF: 8 A
 SG_ G1 : 7|64@0- (1,0) [-1000|1000] "" B
BO_ 103 S64: 8 A
 SG_ H2 : 0|64@1- (3,1) [-1000000|1000000] "" B
SIG_VALTYPE_ 101 F1 : 1;
SIG_VALTYPE_ 102 G1 : 2;
SIG_VALTYPE_ 100 S3 : 1;
'''


def _same(a: float, b: float) -> bool:
    return bool(np.float64(a).view(np.uint64) == np.float64(b).view(np.uint64))


def _messages():
    yield from F.db.messages
    yield from cantools.database.load_string(OTHER_DBC, strict=True).messages


@pytest.mark.parametrize("msg", list(_messages()), ids=lambda m: m.name)
def test_codec_decodes_and_encodes_as_cantools(msg):
    rng = np.random.default_rng(msg.frame_id)
    codec = PayloadCodec(msg)
    pay = rng.integers(0, 256, (200, msg.length), dtype=np.uint8)
    got = codec.decode(pay)
    for k in range(len(pay)):
        ref = msg.decode_simple(pay[k].tobytes(), decode_choices=False, scaling=True)
        assert all(_same(float(v), got[s][k]) for s, v in ref.items()), (k, ref)
    for n in range(1, msg.length):                  # a shorter frame of an older layout
        short = codec.decode(pay[:20], np.full(20, n))
        for k in range(20):
            ref = msg.decode_simple(pay[k, :n].tobytes(), decode_choices=False,
                                    scaling=True, allow_truncated=True)
            assert set(ref) == set(codec.fits(n))
            for s in codec.names:
                assert _same(float(ref[s]), short[s][k]) if s in ref else math.isnan(short[s][k])
    values = {}
    for s in msg.signals:
        lo, hi = float(s.minimum), float(s.maximum)
        v = rng.uniform(lo, hi, 200)
        v[:3] = (lo, hi, (lo + hi) / 2)
        values[s.name] = v
    enc = codec.encode(values)
    for k in range(200):
        ref = msg.encode({s: float(v[k]) for s, v in values.items()}, strict=False)
        assert enc[k].tobytes() == ref, k


def test_fast_line_parser_agrees_with_parse_line():
    good = ["(1700000000.123456) can0 190#E803000040 T", "(1.5) vcan0 080#01",
            "(2.) x 210#0000803F0100 R", "(3.000001)\tcan0  390#0102030405060708 T \r\n",
            "(4.0) can0 701#", "(5.000000) can0 7FF#e8 T\n"]
    other = ["(1.0) can0 12345678#0102 T", "(1.0) can0 190#R T", "(1.0) can0 190##1E8 T",
             "(1.0) can0 800#01 T", "(1.0) can0 0x9#01 T", "(1.0) can0 190#123 T",
             "(1e3) can0 080#07 T", "(1.0) can0 080#01 X", "(.5) can0 080#01 T",
             "(1.0) can0 190#010203040506070809 T", "(1.0)can0 080#01 T", "",
             "(1.0) can0 080#01 T extra", "(١.0) can0 080#01 T", "(1.0) can0 08G#01 T"]
    for line in good:
        m = parse_line(line)
        assert fast_frame(line) == (m.timestamp, m.arbitration_id, bytes(m.data), m.is_rx)
    for line in other:
        assert fast_frame(line) is None, line
    rng = random.Random(13)
    chars = "0123456789ABCDEFabcdef#(). RTx\t"
    for _ in range(3000):                            # damaged lines: never a wrong frame
        s = list(rng.choice(good).rstrip())
        for _ in range(rng.randint(1, 3)):
            s[rng.randrange(len(s))] = rng.choice(chars)
        line = "".join(s)
        fast = fast_frame(line)
        if fast is not None:
            m = parse_line(line)
            assert fast == (m.timestamp, m.arbitration_id, bytes(m.data), m.is_rx), line


class _ValueRows:
    """The old row sink: each row's values as the frames were decoded by cantools."""

    def __init__(self) -> None:
        self.cols: dict[str, list[float]] = {c: [] for c in COLUMNS}
        self.present: list[int] = []

    def __len__(self) -> int:
        return len(self.present)

    def add(self, bus_time_s, run, group) -> None:
        values = {"bus_time_s": bus_time_s, "run": float(run)}
        mask = 0
        if group is not None:
            for name, (_, vals) in group.frames.items():
                values.update(vals)
                mask |= 1 << ROW_FRAMES.index(name)
        for c, col in self.cols.items():
            col.append(values.get(c, math.nan))
        self.present.append(mask)


def _old_path(path):
    """The decoded columns and counts the old way: every line a can.Message from
    `parse_line`, each frame decoded by cantools as it comes (in log order: the
    fixtures here are in time order)."""
    frames, od, _ = _codec(None)
    dec = RowAssembler(frames, int(od[0x1019].default), _ValueRows())
    for msg in read_log(path, LogIssues()):
        dec.feed(msg)
    rows = dec.finish()
    cols = {c: np.array(v, dtype=float) for c, v in rows.cols.items()}
    cols["motor_angle_rad"] = cols.pop("encoder_counts") * TWO_PI / 16384
    return cols, dec.count


def _damaged(tmp_path):
    clean = run(60)
    logs = {"clean": clean}
    seq = run(60)
    del seq[where(seq, 7, "EMA_TPDO2")]
    del seq[where(seq, 20, "SYNC")]
    seq.insert(where(seq, 30, "EMA_TPDO3"), seq[where(seq, 30, "EMA_TPDO3")])
    seq[where(seq, 40, "EMA_TPDO1")].data = bytearray(4)         # a short TPDO1
    seq[where(seq, 41, "EMA_TPDO3")].data = bytearray(3)         # too short: bad
    late = seq.pop(where(seq, 50, "EMA_RPDO1"))
    seq.insert(where(seq, 51, "EMA_TPDO1") + 1, late)
    logs["damaged"] = seq
    out = {}
    for name, msgs in logs.items():
        out[name] = tmp_path / f"{name}.log"
        write_log(out[name], msgs)
    lines = out["damaged"].read_text().splitlines(keepends=True)
    lines[100] = lines[100][:10] + "\n"                          # a cut line
    lines.insert(200, "garbage\n")
    out["damaged"].write_text("".join(lines))
    return out


def _ground_test(n: int = 400) -> Trace:
    t = np.arange(n) * 1e-3
    x = 0.5e-3 * np.sin(2 * np.pi * 2.0 * t)
    cols = {"t_s": t, "setpoint_position_m": x, "setpoint_speed_rad_s": 0.01 * np.cos(t),
            "mode": np.ones(n), "current_a": 0.3 * np.sin(7 * t) - 0.05,
            "motor_angle_rad": 40.0 * x + 1e-4, "motor_speed_rad_s": 3.0 * np.cos(9 * t),
            "position_m": x * 0.99, "temperature_k": 300.0 + t,
            "load_force_n": 500.0 * np.sin(3 * t), "current_demand_a": 0.31 * np.sin(7 * t)}
    return Trace(cols, {"period_s": 1e-3})


def test_decoded_traces_equal_the_old_path(tmp_path):
    logs = _damaged(tmp_path)
    logs["fleet"] = tmp_path / "fleet.log"
    write_candump(_ground_test(), logs["fleet"], 1.7e9)
    for name, path in logs.items():
        tr = trace_from_log(path)
        cols, count = _old_path(path)
        assert set(tr.columns) == set(cols) | {"t_s"}, name
        for c, v in cols.items():
            assert np.array_equal(tr[c].view(np.uint64), v.view(np.uint64)), (name, c)
        assert {k: tr.meta[k] for k in count} == count, name
    meta = trace_from_log(logs["damaged"]).meta
    assert meta["short_frames"] == 1 and meta["bad_frames"] == 1
    assert meta["duplicate_frames"] == 1 and meta["sync_gaps"] == 1
    assert meta["issue_count"] == 2


def test_clean_log_columns_are_each_frames_cantools_values(tmp_path):
    path = tmp_path / "fleet.log"
    write_candump(_ground_test(), path, 1.7e9)
    tr = trace_from_log(path)
    msgs = [parse_line(line) for line in path.read_text().splitlines()][1:]   # after NMT
    assert len(msgs) == 6 * len(tr)
    for k in range(len(tr)):
        for m in msgs[6 * k + 1:6 * k + 6]:
            name, sig = F.decode(m)
            for s, col in SIGNAL_COLUMNS[name]:
                got = tr["motor_angle_rad"][k] * 16384 / TWO_PI if col == "encoder_counts" \
                    else tr[col][k]
                assert got == pytest.approx(float(sig[s]), rel=1e-12, abs=1e-12) \
                    if col == "encoder_counts" else _same(got, float(sig[s])), (k, col)


def _old_write_candump(tr: Trace, t0: float) -> str:
    """The writer before the fast path: every frame encoded by cantools."""
    n, period = len(tr), 1e-3
    angle = np.nan_to_num(tr["motor_angle_rad"])
    values = {
        "SYNC": {"SYNC_Counter": np.arange(n) % 240 + 1.0},
        "ECU_Setpoint": {"SetpointPosition": tr["setpoint_position_m"],
                         "SetpointSpeed": tr["setpoint_speed_rad_s"], "Mode": tr["mode"]},
        "EMA_TPDO1": {"MotorCurrent": tr["current_a"],
                      "StatusWord": np.full(n, float(StatusWord.ENABLED))},
        "EMA_TPDO2": {"EncoderAngle": np.round(angle * 16384 / (2.0 * math.pi)),
                      "EncoderSpeed": tr["motor_speed_rad_s"]},
        "EMA_TPDO3": {"LvdtPosition": tr["position_m"],
                      "WindingTemperature": tr["temperature_k"],
                      "LoadForce": tr["load_force_n"]},
        "EMA_RPDO1": {"CurrentDemand": tr["current_demand_a"],
                      "ControlWord": np.full(n, float(ControlWord.ENABLE))},
    }
    offsets = {"SYNC": 0.0, "ECU_Setpoint": 50e-6, "EMA_TPDO1": 100e-6, "EMA_TPDO2": 110e-6,
               "EMA_TPDO3": 120e-6, "EMA_RPDO1": 300e-6}
    for name, sig in values.items():
        for s, v in sig.items():
            spec = F.by_name[name].get_signal_by_name(s)
            sig[s] = np.clip(v, spec.minimum, spec.maximum).tolist()
    start = F.encode_unchecked("NMT", {"NMT_Command": int(NMTCommand.START),
                                       "NMT_NodeId": F.node_id})
    lines = [f"({t0 - period:.6f}) can0 {start.arbitration_id:03X}#{start.data.hex().upper()} T"]
    for k in range(n):
        t = t0 + k * period
        for name, sig in values.items():
            data = F.by_name[name].encode({s: v[k] for s, v in sig.items()}, strict=False)
            lines.append(f"({t + offsets[name]:.6f}) can0 {F.cob[name]:03X}#"
                         f"{data.hex().upper()} T")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("t0", [1.7e9, 1767596400.0078125, 1000.0])
def test_write_candump_writes_the_old_bytes(tmp_path, t0):
    tr = _ground_test(300)
    path = tmp_path / "g.log"
    write_candump(tr, path, t0)
    assert path.read_text() == _old_write_candump(tr, t0)


def test_stamps_are_formatted_as_python_formats_them():
    rng = np.random.default_rng(5)
    parts = [rng.uniform(1e9, 2.0 ** 33, 3000), rng.uniform(2.0 ** 20, 9e6, 3000),
             1767596400.0 + np.arange(2000) * 2.0 ** -7,        # exact ties: half to even
             1767596400.0 + np.arange(2000) * 1e-3 + 50e-6]
    for part in parts:
        chars = _stamp_chars(part)
        assert chars is not None
        assert chars.tobytes().decode() == "".join(f"{x:.6f}" for x in part)
    assert _stamp_chars(np.array([1000.0])) is None                  # under 2**20 s
    assert _stamp_chars(np.array([9e6, 1.1e7])) is None              # widths differ
