"""dbc/ (the top-level source of ema_contract's bus description): the DBC and the EDS load strictly, round-trip, agree with each other
and with the parameter table, and the codecs built on them keep values within the DBC
quantisation."""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import can
import canopen
import cantools
import pytest
from canopen.objectdictionary import datatypes
from canopen.objectdictionary.eds import export_eds
from hypothesis import given, settings
from hypothesis import strategies as st

from ema_contract.frames import (
    DBC_DIR_ENV,
    SHIPPED_DBC_DIR,
    FrameError,
    Frames,
    dbc_path,
    default_ids,
    eds_path,
    exclude_filters,
    load_db,
    load_od,
)
from ema_contract.states import ControlWord, NMTCommand, NMTState, StatusWord
from plant_rt import eds
from plant_rt.node import EMCY_CONDITIONS
from plant_rt.paramobjects import ParamObjects
from plant_rt.params import PARAMS, PlantParams

ROOT = Path(__file__).resolve().parents[2]


def test_committed_eds_is_the_generator_output():
    assert eds_path().read_text() == eds.build(), \
        "dbc/ema.eds is stale: run python -m plant_rt.eds"


def test_dbc_load_dump_load_round_trip():
    db = cantools.database.load_file(str(dbc_path()), strict=True)
    again = cantools.database.load_string(db.as_dbc_string(), database_format="dbc",
                                          strict=True)
    assert [m.name for m in again.messages] == [m.name for m in db.messages]
    for m in db.messages:
        m2 = again.get_message_by_name(m.name)
        assert (m2.frame_id, m2.length, m2.cycle_time) == (m.frame_id, m.length, m.cycle_time)
        for s in m.signals:
            s2 = m2.get_signal_by_name(s.name)
            assert (s2.start, s2.length, s2.is_signed, s2.is_float, s2.scale, s2.offset,
                    s2.minimum, s2.maximum, s2.unit, s2.byte_order) == \
                (s.start, s.length, s.is_signed, s.is_float, s.scale, s.offset, s.minimum,
                 s.maximum, s.unit, s.byte_order)
            assert dict(s2.choices or {}) == dict(s.choices or {})


def test_eds_load_dump_load_round_trip(tmp_path):
    od = load_od()
    out = tmp_path / "again.eds"
    with out.open("w") as fh:
        export_eds(od, fh)
    od2 = canopen.import_od(str(out), default_ids()[0])
    assert sorted(od.keys()) == sorted(od2.keys())
    for obj in od.values():
        o2 = od2[obj.index]
        assert o2.name == obj.name
        subs = getattr(obj, "subindices", {0: obj})
        for sub, var in subs.items():
            v2 = o2 if sub == 0 and not hasattr(obj, "subindices") else o2[sub]
            assert (v2.name, v2.data_type, v2.access_type) == (var.name, var.data_type,
                                                                 var.access_type)
            if isinstance(var.default, float) and math.isnan(var.default):
                assert math.isnan(v2.default)
            else:
                assert v2.default == var.default


def test_pdo_mapping_matches_dbc():
    db, od = load_db(), load_od()
    node_id = default_ids()[0]
    for m in db.messages:
        if not (m.name.startswith("EMA_") and "PDO" in m.name):
            continue
        tx = "TPDO" in m.name
        num = int(m.name[-1])
        comm = od[(0x1800 if tx else 0x1400) + num - 1]
        mapping = od[(0x1A00 if tx else 0x1600) + num - 1]
        assert comm[1].default == m.frame_id, m.name           # COB-ID, node id resolved
        assert comm[2].default == 1                              # synchronous
        signals = sorted(m.signals, key=lambda s: s.start)
        assert mapping[0].default == len(signals)
        for k, s in enumerate(signals, start=1):
            entry = mapping[k].default
            index, sub, bits = entry >> 16, (entry >> 8) & 0xFF, entry & 0xFF
            var = od[index][sub]
            assert var.name == s.name and bits == s.length == len(var)
            assert var.pdo_mappable
            assert var.factor == pytest.approx(s.scale)
            assert (var.unit or "") == (s.unit or "")
            assert (var.data_type in datatypes.FLOAT_TYPES) == s.is_float
            if not s.is_float:
                assert (var.data_type in datatypes.SIGNED_TYPES) == s.is_signed
    assert od[0x1014].default == 0x80 + node_id
    assert od[0x1006].default == load_db().get_message_by_name("SYNC").cycle_time * 1000


def test_every_parameter_is_an_sdo_object_with_its_type_default_and_range():
    od = load_od()
    objs = ParamObjects(od)
    assert len(objs.by_name) == len(PARAMS)
    for p in PARAMS:
        po = objs.by_name[p.name]
        var = od[po.index][po.subindex]
        assert var.writable and var.readable
        if p.type is bool:
            assert var.data_type == datatypes.BOOLEAN
        elif p.type is int:
            assert var.data_type == datatypes.UNSIGNED32
            assert (var.min, var.max) == (p.min, p.max)
        elif p.type is str:
            assert var.data_type == datatypes.UNSIGNED8
            assert var.default == p.choices.index(p.default)
            assert (var.min, var.max) == (0, len(p.choices) - 1)
        else:
            assert var.data_type == datatypes.REAL64
        if p.unit not in ("-", ""):
            assert var.unit == p.unit
        raw = ParamObjects.to_od(p, p.default)
        back = ParamObjects.from_od(p, var.decode_raw(var.encode_raw(raw)))
        assert back == p.default or (isinstance(back, float) and math.isnan(back))


def test_enums_match_the_dbc_value_tables_and_comments():
    db = load_db()
    hb = db.get_message_by_name("EMA_Heartbeat").get_signal_by_name("EMA_NMTState")
    assert {int(k) for k in hb.choices} == {int(s) for s in NMTState}
    nmt = db.get_message_by_name("NMT").get_signal_by_name("NMT_Command")
    assert {int(k) for k in nmt.choices} == {int(c) for c in NMTCommand}
    comment = db.get_message_by_name("EMA_TPDO1").get_signal_by_name("StatusWord").comment
    parts = {int(n): re.sub(r"[^a-z]", "", text.lower())
             for n, text in re.findall(r"[Bb]it (\d+) ([^;]+)", comment)}
    for flag in StatusWord:
        if flag:
            bit = int(flag).bit_length() - 1
            assert flag.name.replace("_", "").lower() in parts[bit], (flag, parts.get(bit))
    assert len(parts) == len([f for f in StatusWord if f])
    cw = db.get_message_by_name("EMA_RPDO1").get_signal_by_name("ControlWord").comment
    assert "bit 0 enable" in cw.lower() and "bit 7 fault reset" in cw.lower()
    assert ControlWord.ENABLE == 1 and ControlWord.FAULT_RESET == 0x80
    frames = Frames()
    for label, _ in EMCY_CONDITIONS.values():
        frames.choice("EMA_EMCY", "EMCY_ErrorCode", label)   # raises if missing
    for label in ("no_error", "pdo_length"):
        frames.choice("EMA_EMCY", "EMCY_ErrorCode", label)


def test_frames_follow_the_node_id():
    f = Frames(node_id=0x22, ecu_id=0x05)
    assert f.cob["EMA_TPDO1"] == 0x180 + 0x22
    assert f.cob["EMA_RPDO1"] == 0x200 + 0x22
    assert f.cob["EMA_Heartbeat"] == 0x700 + 0x22
    assert f.cob["ECU_Heartbeat"] == 0x705
    assert f.cob["ECU_Setpoint"] == 0x185
    assert f.cob["SYNC"] == 0x80 and f.cob["NMT"] == 0
    assert (f.sdo_rx, f.sdo_tx) == (0x622, 0x5A2)
    with pytest.raises(ValueError):
        Frames(node_id=1, ecu_id=1)
    with pytest.raises(ValueError):
        Frames(node_id=0)


def test_wrong_length_and_unknown_ids():
    f = Frames()
    good = f.encode("EMA_RPDO1", {"CurrentDemand": 1.0, "ControlWord": 1})
    with pytest.raises(FrameError):
        f.decode(can.Message(arbitration_id=good.arbitration_id, data=good.data[:4],
                             is_extended_id=False))
    assert f.decode(can.Message(arbitration_id=0x123, data=b"\0", is_extended_id=False)) is None
    assert f.decode(can.Message(arbitration_id=good.arbitration_id, data=good.data,
                                is_extended_id=True)) is None


def _value_strategy(sig):
    if sig.is_float:
        return st.floats(min_value=sig.minimum, max_value=sig.maximum, allow_nan=False,
                         width=32)
    lo, hi = sig.minimum, sig.maximum
    if sig.scale == 1 and sig.offset == 0:
        return st.integers(min_value=int(lo), max_value=int(hi))
    return st.floats(min_value=lo, max_value=hi, allow_nan=False)


MESSAGES = [m.name for m in load_db().messages]


@pytest.mark.parametrize("name", MESSAGES)
@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_codec_round_trip_within_quantisation(name, data):
    f = Frames()
    m = f.by_name[name]
    values = {s.name: data.draw(_value_strategy(s)) for s in m.signals}
    msg = f.encode(name, values)
    assert len(msg.data) == m.length
    got = f.decode(msg)
    assert got is not None and got[0] == name
    for s in m.signals:
        v, back = values[s.name], got[1][s.name]
        if s.is_float:
            assert back == pytest.approx(v, rel=1e-7, abs=1e-30)
        else:
            assert abs(back - v) <= s.scale / 2 + 1e-12 * max(1.0, abs(v))


@settings(max_examples=50, deadline=None)
@given(excluded=st.integers(min_value=0, max_value=0x7FF),
       probe=st.integers(min_value=0, max_value=0x7FF))
def test_exclude_filters_pass_everything_but_one_id(excluded, probe):
    filters = exclude_filters([excluded])
    passes = any((probe & f["can_mask"]) == (f["can_id"] & f["can_mask"]) for f in filters)
    assert passes == (probe != excluded)


def test_resolutions_are_far_below_sensor_noise():
    noise = PlantParams().sensors
    db = load_db()
    scale = {s.name: s.scale for m in db.messages for s in m.signals}
    assert scale["LvdtPosition"] <= noise.position_noise_m / 100
    assert scale["MotorCurrent"] <= noise.current_noise_a / 100
    assert scale["EncoderSpeed"] <= noise.speed_noise_rad_s / 100


def test_generator_check_mode(capsys):
    assert eds.main(["--check"]) == 0
    assert "up to date" in capsys.readouterr().out


def test_no_frame_layout_in_python_sources():
    """Frame layouts live in dbc/ only: no struct formats in the bus code."""
    pattern = re.compile(r"struct\.(pack|unpack|Struct)\(")
    ecu = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "bench/ecu").glob("*.py"))
    assert ecu, "bench/ecu/ (the ECU package) has no modules"
    for rel in ("plant_rt/node.py", "ema_contract/frames.py", *ecu, "bench/bus/logs.py",
                "bench/bus/__init__.py"):
        assert not pattern.search((ROOT / rel).read_text()), rel


def test_dbc_dir_env_points_at_another_description(tmp_path, monkeypatch):
    """$EMA_BENCH_DBC_DIR replaces the shipped DBC and EDS (a real actuator's files)."""
    for name in ("ema.dbc", "ema.eds"):
        shutil.copy(SHIPPED_DBC_DIR / name, tmp_path / name)
    monkeypatch.setenv(DBC_DIR_ENV, str(tmp_path))
    assert (dbc_path(), eds_path()) == (tmp_path / "ema.dbc", tmp_path / "ema.eds")
    assert Frames().node_id == 0x10 and 0x2000 in load_od()
    monkeypatch.setenv(DBC_DIR_ENV, str(tmp_path / "missing"))
    with pytest.raises(FileNotFoundError, match=DBC_DIR_ENV):
        load_db()
    monkeypatch.delenv(DBC_DIR_ENV)
    assert dbc_path() == SHIPPED_DBC_DIR / "ema.dbc"


def test_a_checkout_reads_the_top_level_dbc():
    """Run from a checkout, the shipped pair is the repository's dbc/, the one copy: no
    ema_contract/dbc/ in the tree (a stale copy there would shadow the source)."""
    assert SHIPPED_DBC_DIR == ROOT / "dbc"
    assert (ROOT / "dbc" / "ema.dbc").is_file() and (ROOT / "dbc" / "ema.eds").is_file()
    assert not (ROOT / "ema_contract" / "dbc").exists()
    assert eds.DBC == ROOT / "dbc" / "ema.dbc" and eds.EDS == ROOT / "dbc" / "ema.eds"


def test_an_installed_package_reads_its_own_copy(tmp_path, monkeypatch):
    """In a wheel the pair is package data, ema_contract/dbc/, found through
    importlib.resources; without it (a checkout) the top-level dbc/ next to the package."""
    from ema_contract import frames
    (tmp_path / "dbc").mkdir()
    monkeypatch.setattr(frames.resources, "files", lambda package: tmp_path)
    assert frames._shipped_dbc_dir() == ROOT / "dbc"          # no ema.dbc in the copy
    shutil.copy(SHIPPED_DBC_DIR / "ema.dbc", tmp_path / "dbc" / "ema.dbc")
    assert frames._shipped_dbc_dir() == tmp_path / "dbc"
