"""`bench up` / `bench status` / `bench down`: the bench's background bus and plant."""

from __future__ import annotations

import argparse
import math
import sys
import time
from contextlib import contextmanager

from bench import BenchError
from bench.cli import options as opt


def add_subparser(sub: argparse._SubParsersAction) -> None:
    up = opt.add_command(sub, "up", "start the loopback bus and the plant in the background", """
        Start the loopback CAN hub (when no bus is configured and there is no vcan0) and the
        plant node in the background; their pids and logs are kept in the state directory
        ($BENCH_STATE_DIR, $XDG_RUNTIME_DIR/ema-bench or ./.bench).""")
    up.add_argument("--pace", choices=["realtime", "sync"], default="realtime",
                    help="the plant's pacer at start (a run may switch it; default: "
                         "%(default)s)")
    opt.add_set(up, "plant parameter at start (repeatable)", dest="assignments")
    opt.add_node_id(up)
    opt.add_serial(up)
    up.add_argument("--rt-priority", type=int, default=0, metavar="N",
                    help="start hub and plant under SCHED_FIFO at priority N (1-99; needs "
                         "root or CAP_SYS_NICE); 0: normal scheduling (default)")
    opt.add_bus(up)
    up.set_defaults(func=cmd_up)

    st = opt.add_command(sub, "status", "show the plant node's state, counters and parameters", """
        Read the actuator node's NMT state, status word, counters and parameters by SDO. Answers
        within about 2 s when no plant is there.""")
    st.add_argument("--all", action="store_true",
                    help="list every parameter (default: only those not at their default)")
    opt.add_node_id(st)
    opt.add_bus(st)
    st.set_defaults(func=cmd_status)

    dn = opt.add_command(sub, "down", "stop the background plant and loopback bus", """
        Stop what `bench up` started (plant, then hub).""")
    dn.set_defaults(func=cmd_down)


LOCK_TIMEOUT_S = 150.0   # a `bench up` holding the lock may compile the plant (90 s at most)


@contextmanager
def _locked(what: str):
    """The state directory's lock around a check-and-start or a stop (BenchError after
    LOCK_TIMEOUT_S); says so when another `bench up`/`bench down` makes it wait."""
    from ema_contract.transport import StateLocked, state_dir, state_lock

    def waiting() -> None:
        print(f"{what}: waiting for another `bench up`/`bench down` on {state_dir()}",
              file=sys.stderr, flush=True)

    try:
        with state_lock(LOCK_TIMEOUT_S, waiting):
            yield
    except StateLocked as exc:
        raise BenchError(str(exc)) from None


def cmd_up(args: argparse.Namespace) -> int:
    from plant_rt.params import ParameterError, PlantParams

    try:
        PlantParams().with_assignments(args.assignments)
    except ParameterError as exc:
        raise BenchError(str(exc)) from None
    if not 0 <= args.rt_priority <= 99:
        raise BenchError("--rt-priority must be within 0..99")
    with _locked("up"):
        return _up(args)


def _up(args: argparse.Namespace) -> int:
    """Check-and-start, under the state lock."""
    from bench.bus import bus_settings, find_bus
    from bench.bus.procs import start_hub, start_plant
    from ema_contract.transport import PLANT_FILE, hub_label, read_state, state_dir, write_state
    from plant_rt.pacing import use_normal_priority, use_realtime_priority

    plant = read_state(PLANT_FILE)
    if plant:
        print(f"already up: plant pid {plant['pid']} on {plant['bus']}, pace "
              f"{plant.get('pace', '?')}, state {state_dir()} (`bench down` first to "
              f"restart)")
        return 0
    found = find_bus(bus_settings(args))
    started = []
    if args.rt_priority:     # the hub and the plant started below inherit the policy
        print(f"scheduling: {use_realtime_priority(args.rt_priority)}")
    try:
        if found is None:
            hub = start_hub(persistent=True)
            started.append(hub)
            cfg, source = {"interface": "remote", "channel": hub.info["url"]}, hub_label()
            print(f"hub: pid {hub.pid}, {hub.info['url']} (127.0.0.1 only)")
        else:
            cfg, source = found
        with _boot_wait(args.pace) as on_wait:
            child = start_plant(cfg, pace=args.pace, assignments=args.assignments,
                                persistent=True, node_id=args.node_id, serial=args.serial,
                                on_wait=on_wait)
    except BaseException:
        for c in started:
            c.stop()
        raise
    finally:
        use_normal_priority()
    bus = f"{cfg.get('interface')}:{cfg.get('channel')}"
    write_state(PLANT_FILE, {"pid": child.pid, "bus": bus, "source": source,   # + "start"
                             "pace": args.pace, "log": str(child.log_path),
                             "started": time.time()})
    print(f"plant: pid {child.pid}, node 0x{(args.node_id or 0x10):02X} on {bus} ({source}), "
          f"pace {args.pace}; log {child.log_path}")
    print(f"state: {state_dir()}")
    return 0


@contextmanager
def _boot_wait(pace: str):
    """What `bench up` waits for, said on stderr, with the time waited (a tqdm counter,
    on a terminal): the plant's boot-up, which at its first start compiles the physics."""
    print(f"plant: starting (pace {pace}); waiting for its boot-up (the first start "
          "compiles the physics: up to a minute)", file=sys.stderr, flush=True)
    from tqdm import tqdm
    bar = tqdm(desc="waiting for the plant", bar_format="{desc}: {elapsed}", leave=False,
               disable=None, file=sys.stderr)

    shown = [0.0]

    def on_wait(elapsed_s: float) -> None:
        if elapsed_s - shown[0] >= 0.5:
            shown[0] = elapsed_s
            bar.refresh()

    try:
        yield on_wait
    finally:
        bar.close()


def _fmt(v) -> str:
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:g}"
    return str(v)


def cmd_status(args: argparse.Namespace) -> int:
    from bench.bus import bus_settings, close_bus, connect, find_bus
    from bench.ecu import MISSING, Ecu, status_names
    from ema_contract.states import NMTState, Pace
    from ema_contract.transport import HUB_FILE, PLANT_FILE, read_state, state_dir
    from plant_rt.params import PlantParams

    hub, plant = read_state(HUB_FILE), read_state(PLANT_FILE)
    found = find_bus(bus_settings(args))
    if found is None:
        raise BenchError(f"bench is not up: no loopback hub running (state {state_dir()}), "
                         "no vcan0 and no python-can configuration (run `bench up`)")
    print(f"state: {state_dir()}")
    cfg, source = found
    print(f"bus: {cfg.get('interface')}:{cfg.get('channel')} ({source})"
          + (f", hub pid {hub['pid']}" if hub else ""))
    if plant:
        print(f"plant process: pid {plant['pid']}, log {plant.get('log', '?')}")
    bus = connect(cfg, timeout=2.0)
    ecu = None
    try:
        ecu = Ecu(bus, node_id=args.node_id, echo=False, sdo_timeout_s=0.25)
        state = ecu.wait_for_plant(0.35)
        st = ecu.read_status()
        pace = ecu.read_optional("node_control.pace")
        params = ecu.read_params()
        ident = ecu.read_identity()
    finally:
        if ecu is not None:
            ecu.close()
        close_bus(bus)
    if st:
        word = int(st["status_word"])
        pace_name = "?" if pace is MISSING else Pace(int(pace)).name.lower()
        print(f"node 0x{ecu.node_id:02X}: {NMTState(state).name}, pace {pace_name}, plant "
              f"time {st['plant_time_s']:.3f} s, status 0x{word:04X} "
              f"({', '.join(status_names(word)) or 'ok'})")
        print("counters: " + ", ".join(f"{k} {_fmt(v)}" for k, v in st.items()
                                       if k not in ("nmt_state", "status_word",
                                                    "plant_time_s")))
    else:     # a node with only CiA 301 objects (docs/node-contract.md)
        print(f"node 0x{ecu.node_id:02X}: {NMTState(state).name}, identity "
              + ", ".join(f"{k} 0x{v:X}" for k, v in ident.items()))
    if ecu.missing:
        print(f"missing optional objects: {', '.join(ecu.missing)}")
    if not ecu.node_info.params:
        print("parameters: none read back")
        return 0
    diff = PlantParams().diff(params)
    shown = params.flat() if args.all else {k: b for k, (_, b) in diff.items()}
    title = "parameters" if args.all else "parameters not at their default"
    print(f"{title}: " + ("none" if not shown else ""))
    for k, v in shown.items():
        print(f"  {k} = {_fmt(v)}")
    return 0


def cmd_down(args: argparse.Namespace) -> int:  # noqa: ARG001
    from bench.bus.procs import MODULES, stop_pid
    from ema_contract.transport import HUB_FILE, PLANT_FILE, read_state, remove_state, state_dir

    did = False
    with _locked("down"):
        for name, label in ((PLANT_FILE, "plant"), (HUB_FILE, "hub")):
            st = read_state(name)      # None for a stale or corrupt record (reported)
            if st:
                stop_pid(st["pid"], token=st.get("start"), module=MODULES[label])
                print(f"stopped {label} (pid {st['pid']}) of the bench in {state_dir()}")
                did = True
                remove_state(name, st["pid"])
    if not did:
        print(f"nothing to stop (no bench running from {state_dir()})", file=sys.stderr)
    return 0
