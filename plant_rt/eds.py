"""Write ema_contract/dbc/ema.eds, the actuator's CANopen object dictionary, from its two
sources.

- the PDOs (communication and mapping parameters, process-data objects, data types,
  scaling factors and units), the node ids, SYNC period, heartbeat times and the SYNC
  counter come from `ema_contract/dbc/ema.dbc`, so the EDS and the DBC cannot disagree;
- the manufacturer parameter objects (0x2000-0x2008, one record per parameter group,
  one sub-index per parameter, in `plant_rt.params.PARAMS` order) come from the plant's
  parameter table, so every settable parameter is an SDO object with its unit, range,
  default and description.

The node's own status, counters and control objects (0x2100, 0x2200) are declared here.
Output is deterministic (no dates). Usage:

    python -m plant_rt.eds            # rewrite ema_contract/dbc/ema.eds
    python -m plant_rt.eds --check    # exit 1 if ema_contract/dbc/ema.eds is stale

A unit test checks that the committed EDS equals this module's output. It lives in the
plant package because the parameter objects are the simulated plant's (`plant_rt.params`);
the contract package (`ema_contract`) ships its output and imports nothing of the plant.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import cantools

from ema_contract.frames import PACKAGE_DBC_DIR
from plant_rt.params import GROUPS, PARAMS

DBC = PACKAGE_DBC_DIR / "ema.dbc"
EDS = PACKAGE_DBC_DIR / "ema.eds"

# CiA 301 data type codes
BOOLEAN, INTEGER8, INTEGER16, INTEGER32 = 0x1, 0x2, 0x3, 0x4
UNSIGNED8, UNSIGNED16, UNSIGNED32, REAL32, REAL64 = 0x5, 0x6, 0x7, 0x8, 0x11
INTEGER24, UNSIGNED24 = 0x10, 0x16

# EMCY inhibit time 0x1015 (100 us units): 100 ms, the node's other event time (heartbeat
# period, condition re-arm); EMCYs at most 10/s, ~0.13 % of a 1 Mbit/s bus
EMCY_INHIBIT_100US = 1000

PARAM_BASE = 0x2000     # + group number: plant parameter records
STATUS_INDEX = 0x2100   # node status and counters
CONTROL_INDEX = 0x2200  # node control (pace, plant reset, counter reset)
TX_INDEX = 0x2300       # process data the actuator transmits (TPDO-mapped)
RX_INDEX = 0x2400       # process data the actuator receives (RPDO-mapped)

# (name, data type, access, default, unit, description): the node's status objects
STATUS = [
    ("nmt_state", UNSIGNED8, "ro", 0, "", "NMT state: 0 boot-up, 4 stopped, 5 operational, "
     "127 pre-operational"),
    ("status_word", UNSIGNED16, "ro", 0, "", "actuator status word (bits as in EMA_TPDO1 "
     "StatusWord of ema_contract/dbc/ema.dbc)"),
    ("frames_received", UNSIGNED32, "ro", 0, "", "CAN frames received since the last reset"),
    ("bad_frames", UNSIGNED32, "ro", 0, "", "frames with a known id but a wrong length, "
     "ignored"),
    ("unknown_frames", UNSIGNED32, "ro", 0, "", "frames with an id this node does not use, "
     "ignored"),
    ("demands_invalid", UNSIGNED32, "ro", 0, "", "RPDO current demands that were NaN (replaced "
     "by 0) or beyond motor.current_max_a (clamped)"),
    ("sync_received", UNSIGNED32, "ro", 0, "", "SYNC frames received"),
    ("cycles", UNSIGNED32, "ro", 0, "", "plant periods integrated since the plant reset"),
    ("deadline_misses", UNSIGNED32, "ro", 0, "", "real-time pacer: periods whose step finished "
     "after the next period's release"),
    ("jitter_p50_us", REAL32, "ro", 0.0, "us", "real-time pacer: median lateness of the "
     "period release"),
    ("jitter_p99_us", REAL32, "ro", 0.0, "us", "real-time pacer: 99th percentile lateness"),
    ("jitter_max_us", REAL32, "ro", 0.0, "us", "real-time pacer: largest lateness"),
    ("plant_time_s", REAL64, "ro", 0.0, "s", "simulated time of the plant"),
    ("heartbeat_timeouts", UNSIGNED32, "ro", 0, "", "ECU heartbeat losses (demand forced to 0)"),
    ("emcy_sent", UNSIGNED32, "ro", 0, "", "EMCY frames sent"),
    ("rpdo_missing", UNSIGNED32, "ro", 0, "", "SYNCs in OPERATIONAL with no new RPDO since the "
     "previous SYNC (the last command was held)"),
    ("applied_demand_a", REAL32, "ro", 0.0, "A", "current demand the drive holds this period"),
    ("skipped_periods", UNSIGNED32, "ro", 0, "", "real-time pacer: periods dropped after a "
     "stall longer than 50 periods"),
    ("sync_counter_gaps", UNSIGNED32, "ro", 0, "", "SYNC counter jumps (lost SYNC frames)"),
    ("step_time_p99_us", REAL32, "ro", 0.0, "us", "99th percentile of the wall time one plant "
     "period takes to integrate"),
    ("emcy_suppressed", UNSIGNED32, "ro", 0, "", "EMCYs not sent because of the inhibit time "
     "(0x1015): repeats of an error code replaced by a later one, which is sent"),
]
CONTROL = [
    ("pace", UNSIGNED8, "rw", 0, "", "pacer: 0 realtime (wall clock, absolute deadlines), "
     "1 sync (one period per SYNC, lockstep); writable in pre-operational"),
    ("reset_plant", UNSIGNED8, "wo", 0, "", "write 1 in pre-operational: restart the plant at "
     "t = 0 with the current parameters"),
    ("reset_counters", UNSIGNED8, "wo", 0, "", "write 1: zero the counters and jitter "
     "statistics of 0x2100"),
    ("spin_us", UNSIGNED32, "rw", 200, "us", "real-time pacer: busy-wait window before each "
     "release (sleep until then)"),
]


@dataclass
class Var:
    index: int
    sub: int | None
    name: str
    dtype: int
    access: str
    default: object = None
    pdo: bool = False
    low: object = None
    high: object = None
    unit: str = ""
    factor: float = 1.0
    description: str = ""


def _fmt_default(dtype: int, value: object) -> str:
    if isinstance(value, str):           # $NODEID+0x... expressions
        return value
    if dtype in (REAL32, REAL64):
        v = float(value)  # type: ignore[arg-type]
        return "nan" if math.isnan(v) else repr(v)
    if dtype == BOOLEAN:
        return "1" if value else "0"
    n = int(value)  # type: ignore[call-overload]
    return f"0x{n:X}" if n >= 0x10000 else str(n)  # mapping entries and ids in hex


def _fmt_limit(dtype: int, value: object) -> str:
    if dtype in (REAL32, REAL64):
        return repr(float(value))  # type: ignore[arg-type]
    return str(int(value))  # type: ignore[call-overload]


def _signal_dtype(sig) -> int:
    if sig.is_float:
        return REAL32 if sig.length == 32 else REAL64
    table = {(8, True): INTEGER8, (16, True): INTEGER16, (24, True): INTEGER24,
             (32, True): INTEGER32, (8, False): UNSIGNED8, (16, False): UNSIGNED16,
             (24, False): UNSIGNED24, (32, False): UNSIGNED32, (1, False): BOOLEAN}
    try:
        return table[(sig.length, sig.is_signed)]
    except KeyError:
        raise SystemExit(f"{DBC.name}: signal {sig.name} has no CANopen data type "
                         f"({sig.length} bits)") from None


def _node_address(db, name: str) -> int:
    node = next(n for n in db.nodes if n.name == name)
    return int(node.dbc.attributes["NmStationAddress"].value)


def _cycle_ms(msg) -> int:
    return int(msg.cycle_time or 0)


def build() -> str:
    db = cantools.database.load_file(str(DBC), strict=True)
    ema = _node_address(db, "EMA")
    ecu = _node_address(db, "ECU")
    msgs = {m.name: m for m in db.messages}
    sync_ms = _cycle_ms(msgs["SYNC"])
    hb_ms = _cycle_ms(msgs["EMA_Heartbeat"])
    ecu_hb_ms = _cycle_ms(msgs["ECU_Heartbeat"])
    sync_max = int(msgs["SYNC"].get_signal_by_name("SYNC_Counter").maximum)

    objs: list[tuple[int, str, list[Var] | Var]] = []   # (index, name, var or members)

    def var(index, name, dtype, access, default=None, **kw) -> None:
        objs.append((index, name, Var(index, None, name, dtype, access, default, **kw)))

    def record(index, name, members: list[Var], kind: str = "record") -> None:
        sub0 = Var(index, 0, "Highest sub-index supported", UNSIGNED8, "const",
                   max(m.sub or 0 for m in members))
        objs.append((index, f"{kind}:{name}", [sub0, *members]))

    # -- communication profile (CiA 301) ----------------------------------------------
    var(0x1000, "Device type", UNSIGNED32, "ro", 0)
    var(0x1001, "Error register", UNSIGNED8, "ro", 0, pdo=True)
    var(0x1005, "COB-ID SYNC", UNSIGNED32, "rw", msgs["SYNC"].frame_id)
    var(0x1006, "Communication cycle period", UNSIGNED32, "rw", sync_ms * 1000, unit="us",
        description="SYNC period; the plant's sim.sync_period_s follows it")
    var(0x1014, "COB-ID EMCY", UNSIGNED32, "ro",
        f"$NODEID+0x{msgs['EMA_EMCY'].frame_id - ema:X}")
    record(0x1016, "Consumer heartbeat time", [
        Var(0x1016, 1, "Consumer heartbeat time 1", UNSIGNED32, "rw",
            (ecu << 16) | (3 * ecu_hb_ms),
            description="ECU node id << 16 | timeout in ms (3 ECU heartbeat periods); in "
                        "lockstep (pace sync) counted in SYNC periods: timeout / SYNC period")],
        kind="array")
    var(0x1017, "Producer heartbeat time", UNSIGNED16, "rw", hb_ms, unit="ms")
    record(0x1018, "Identity object", [
        Var(0x1018, 1, "Vendor-ID", UNSIGNED32, "ro", 0),
        Var(0x1018, 2, "Product code", UNSIGNED32, "ro", 1),
        Var(0x1018, 3, "Revision number", UNSIGNED32, "ro", 0x10000),
        Var(0x1018, 4, "Serial number", UNSIGNED32, "ro", 0)])
    var(0x1019, "Synchronous counter overflow value", UNSIGNED8, "rw", sync_max)
    var(0x1015, "Inhibit time EMCY", UNSIGNED16, "rw", EMCY_INHIBIT_100US, unit="100 us",
        description="at most one EMCY per inhibit time (default 100 ms); repeats within it "
                    "are counted (0x2100 emcy_suppressed), the latest state of each error "
                    "code is sent when it ends; the node's log lines are limited alike; "
                    "in lockstep it runs on the SYNC time base while operational; 0: no limit")
    record(0x1029, "Error behavior", [
        Var(0x1029, 1, "Communication error", UNSIGNED8, "rw", 0, low=0, high=2,
            description="on a lost ECU heartbeat (demand forced to 0, EMCY 0x8130, status "
                        "bit 4): 0 change to pre-operational if operational, 1 no state "
                        "change, 2 change to stopped")], kind="array")
    record(0x1200, "SDO server parameter", [
        Var(0x1200, 1, "COB-ID client to server", UNSIGNED32, "ro", "$NODEID+0x600"),
        Var(0x1200, 2, "COB-ID server to client", UNSIGNED32, "ro", "$NODEID+0x580")])

    # -- PDOs, from the DBC ------------------------------------------------------------
    tx_vars: dict[str, Var] = {}
    rx_vars: dict[str, Var] = {}
    pdos = sorted((m for m in db.messages if "PDO" in m.name and m.name.startswith("EMA_")),
                  key=lambda m: m.frame_id)
    for m in pdos:
        tx = "TPDO" in m.name
        store, base = (tx_vars, TX_INDEX) if tx else (rx_vars, RX_INDEX)
        for s in sorted(m.signals, key=lambda s: s.start):
            if s.byte_order != "little_endian" or s.start % 8:
                raise SystemExit(f"{DBC.name}: {s.name} is not byte-aligned little-endian")
            store[s.name] = Var(base, len(store) + 1, s.name, _signal_dtype(s),
                                "ro" if tx else "rww", 0.0 if s.is_float else 0, pdo=True,
                                unit=s.unit or "", factor=float(s.scale),
                                description=(s.comment or "").replace("\n", " "))
    record(TX_INDEX, "tx_process_data", list(tx_vars.values()))
    record(RX_INDEX, "rx_process_data", list(rx_vars.values()))

    n_tx = n_rx = 0
    for m in pdos:
        tx = "TPDO" in m.name
        num = int(m.name[-1])
        fn = m.frame_id - ema
        comm = (0x1800 if tx else 0x1400) + num - 1
        mapping = comm + 0x200
        n_tx, n_rx = (n_tx + 1, n_rx) if tx else (n_tx, n_rx + 1)
        members = [Var(comm, 1, "COB-ID used by PDO", UNSIGNED32, "rw", f"$NODEID+0x{fn:X}"),
                   Var(comm, 2, "Transmission type", UNSIGNED8, "rw", 1,
                       description="1: synchronous, every SYNC")]
        if tx:
            members += [Var(comm, 3, "Inhibit time", UNSIGNED16, "rw", 0, unit="100 us"),
                        Var(comm, 5, "Event timer", UNSIGNED16, "rw", 0, unit="ms")]
        record(comm, f"{'TPDO' if tx else 'RPDO'}{num} communication parameter", members)
        store = tx_vars if tx else rx_vars
        maps = []
        for k, s in enumerate(sorted(m.signals, key=lambda s: s.start), start=1):
            v = store[s.name]
            maps.append(Var(mapping, k, f"Mapped object {k}", UNSIGNED32, "rw",
                            (v.index << 16) | (v.sub << 8) | s.length))  # type: ignore[operator]
        record(mapping, f"{'TPDO' if tx else 'RPDO'}{num} mapping parameter", maps)

    # -- plant parameters ---------------------------------------------------------------
    for gnum, group in enumerate(GROUPS):
        members = []
        infos = [p for p in PARAMS if p.group == group]
        for sub, info in enumerate(infos, start=1):
            desc = info.doc
            if info.source:
                desc += f" [{info.source}]"
            low = high = None
            default = info.default
            if info.type is bool:
                dtype = BOOLEAN
            elif info.type is int:
                dtype, low, high = UNSIGNED32, info.min, info.max
            elif info.type is str:
                choices = info.choices or ()
                dtype, low, high = UNSIGNED8, 0, len(choices) - 1
                default = choices.index(info.default)
                desc += " (" + ", ".join(f"{i}={c}" for i, c in enumerate(choices)) + ")"
            else:
                dtype, low, high = REAL64, info.min, info.max
            members.append(Var(PARAM_BASE + gnum, sub, info.leaf, dtype, "rw", default,
                               low=low, high=high, unit=info.unit if info.unit != "-" else "",
                               description=desc))
        record(PARAM_BASE + gnum, group, members)

    # -- node status and control -----------------------------------------------------
    record(STATUS_INDEX, "node_status", [
        Var(STATUS_INDEX, k, n, t, a, d, unit=u, description=doc)
        for k, (n, t, a, d, u, doc) in enumerate(STATUS, start=1)])
    record(CONTROL_INDEX, "node_control", [
        Var(CONTROL_INDEX, k, n, t, a, d, unit=u, description=doc)
        for k, (n, t, a, d, u, doc) in enumerate(CONTROL, start=1)])

    return _render(sorted(objs, key=lambda o: o[0]), n_rx, n_tx, ema)


def _render(objs, n_rx: int, n_tx: int, node_id: int) -> str:
    out: list[str] = []
    w = out.append
    w("; EMA actuator node: CANopen electronic data sheet (CiA 306).")
    w("; GENERATED by python -m plant_rt.eds from ema_contract/dbc/ema.dbc and plant_rt/params.py;")
    w("; do not edit by hand (a unit test checks this file equals the generator's output).")
    w("")
    w("[FileInfo]")
    w("FileName=ema.eds")
    w("FileVersion=1")
    w("FileRevision=0")
    w("EDSVersion=4.0")
    w("Description=EMA ball-screw actuator plant (ema-hums-bench)")
    w("CreatedBy=plant_rt/eds.py")
    w("")
    w("[DeviceInfo]")
    w("VendorName=ema-hums-bench")
    w("VendorNumber=0")
    w("ProductName=EMA ball-screw actuator plant")
    w("ProductNumber=1")
    w("RevisionNumber=0x10000")
    w("OrderCode=ema-plant")
    for rate in (10, 20, 50, 125, 250, 500, 800, 1000):
        w(f"BaudRate_{rate}={1 if rate == 1000 else 0}")
    w("SimpleBootUpMaster=0")
    w("SimpleBootUpSlave=1")
    w("Granularity=8")
    w("DynamicChannelsSupported=0")
    w("GroupMessaging=0")
    w(f"NrOfRXPDO={n_rx}")
    w(f"NrOfTXPDO={n_tx}")
    w("LSS_Supported=0")
    w("")
    w("[DummyUsage]")
    for i in range(1, 8):
        w(f"Dummy{i:04d}=0")
    w("")
    w("[Comments]")
    comments = [f"Default node id 0x{node_id:02X} (DBC attribute NmStationAddress).",
                "0x2000-0x2008: plant parameters, one record per group of plant_rt.params "
                "(writable in PRE-OPERATIONAL only).",
                "0x2100: node status and counters; 0x2200: node control; 0x2300/0x2400: "
                "process data mapped into the PDOs of ema_contract/dbc/ema.dbc."]
    w(f"Lines={len(comments)}")
    for i, line in enumerate(comments, start=1):
        w(f"Line{i}={line}")
    w("")
    mandatory = [o for o in objs if o[0] in (0x1000, 0x1001, 0x1018)]
    optional = [o for o in objs if o[0] < 0x2000 and o not in mandatory]
    manufacturer = [o for o in objs if 0x2000 <= o[0] < 0x6000]
    for title, group in (("MandatoryObjects", mandatory), ("OptionalObjects", optional),
                         ("ManufacturerObjects", manufacturer)):
        w(f"[{title}]")
        w(f"SupportedObjects={len(group)}")
        for i, (index, _, _) in enumerate(group, start=1):
            w(f"{i}=0x{index:04X}")
        w("")
        for index, name, body in group:
            if isinstance(body, Var):
                _render_var(w, body, f"{index:04X}")
            else:
                kind, _, rname = name.partition(":")
                w(f"[{index:04X}]")
                w(f"ParameterName={rname}")
                w(f"ObjectType={'0x8' if kind == 'array' else '0x9'}")
                w(f"SubNumber=0x{len(body):X}")
                w("")
                for v in body:
                    _render_var(w, v, f"{index:04X}sub{v.sub:X}")
    return "\n".join(out).rstrip("\n") + "\n"


def _render_var(w, v: Var, section: str) -> None:
    w(f"[{section}]")
    w(f"ParameterName={v.name}")
    w("ObjectType=0x7")
    w(f"DataType=0x{v.dtype:04X}")
    w(f"AccessType={v.access}")
    if v.default is not None:
        w(f"DefaultValue={_fmt_default(v.dtype, v.default)}")
    if v.low is not None:
        w(f"LowLimit={_fmt_limit(v.dtype, v.low)}")
    if v.high is not None:
        w(f"HighLimit={_fmt_limit(v.dtype, v.high)}")
    w(f"PDOMapping={1 if v.pdo else 0}")
    if v.factor != 1.0:
        w(f"Factor={v.factor!r}")
    if v.unit:
        w(f"Unit={v.unit}")
    if v.description:
        w(f"Description={v.description}")
    w("")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if the EDS is out of date")
    ap.add_argument("-o", "--output", default=str(EDS), help="where to write (default: %(default)s)")
    args = ap.parse_args(argv)
    text = build()
    if args.check:
        current = EDS.read_text() if EDS.exists() else ""
        if current != text:
            print(f"{EDS} is out of date: run python -m plant_rt.eds", file=sys.stderr)
            return 1
        print(f"{EDS} is up to date")
        return 0
    Path(args.output).write_text(text)
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
