"""`bench run PROFILE`: the ECU runs a profile against the plant over the CAN bus."""

from __future__ import annotations

import argparse
import inspect
import math
import signal
import sys
from collections import Counter

import numpy as np

from bench import BenchError
from bench.cli import options as opt


def _profile_flags() -> dict[str, str]:
    """Profile keyword -> flag, for every keyword of every profile except duration_s."""
    from bench.profiles.catalog import PROFILES
    out: dict[str, str] = {}
    for factory in PROFILES.values():
        for name in inspect.signature(factory).parameters:
            if name != "duration_s":
                out[name] = "--" + name.replace("_", "-")
    return out


def add_subparser(sub: argparse._SubParsersAction) -> None:
    from bench.profiles.catalog import PROFILES, profile_args
    lines = []
    for name in PROFILES:
        args = ", ".join(f"{k}={v:g}" if isinstance(v, (int, float)) and v is not None
                         else f"{k}={v}" for k, v in profile_args(name).items())
        lines.append(f"  {name}: {args}")
    p = sub.add_parser(
        "run", help="run a profile against the plant over the CAN bus (the ECU)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="The ECU as a CANopen master (NMT, SYNC producer, heartbeat) runs the "
        "position/speed controller against the plant over the bus. Starts a loopback hub and "
        "a plant for the run when `bench up` was not run.\n\nprofiles and their parameters "
        "(flags --name-with-dashes):\n" + "\n".join(lines))
    p.add_argument("profile", choices=list(PROFILES), metavar="PROFILE",
                   help="one of: " + ", ".join(PROFILES))
    p.add_argument("--pace", choices=["realtime", "sync"], default=None,
                   help="realtime: SYNC on wall-clock deadlines (after a 0.2 s calibration "
                        "that says whether this machine holds them now); sync: lockstep, "
                        "as fast as the bus allows, exact on any load. Default: the pace of "
                        "the plant found (`bench up --pace`, read from object 0x2200 sub "
                        "1), realtime for a plant started for the run or a node without "
                        "lockstep")
    p.add_argument("--stamp", choices=["bus", "wall"], default="bus",
                   help="time stamps of the --log: bus (default) is the bus's own time, "
                        "in lockstep the SYNC count x the period from the run's start (so "
                        "that a log of 1000 SYNCs spans 1 s, for canplayer and plots); "
                        "wall: the wall clock as the ECU sent and read each frame (a "
                        "real-time run's bus time)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="run length (s); the profile's own by default")
    opt.add_set(p, "plant parameter, written by SDO before the run (repeatable; see "
                "`bench plant --list-params`)", dest="assignments")
    p.add_argument("--log", metavar="FILE.log", help="log of every frame: candump .log, or "
                   ".asc, .blf, .trc, .mf4 (python-can's writers)")
    p.add_argument("--save", metavar="TRACE", help="save the trace (.csv, .parquet or .npz)")
    p.add_argument("--spin-us", type=int, default=200, metavar="US",
                   help="real-time pacers (ECU and plant): busy-wait window before each "
                        "period (default: %(default)s us)")
    p.add_argument("--rt-priority", type=int, default=0, metavar="N",
                   help="run the ECU (and the hub and plant it starts) under SCHED_FIFO at "
                        "priority N (1-99; needs root or CAP_SYS_NICE); 0: normal scheduling "
                        "(default)")
    p.add_argument("--no-plant", action="store_true",
                   help="never start a plant (a real actuator must answer)")
    opt.add_node_id(p)
    opt.add_serial(p, "; for the plant this run starts when none answers")
    p.add_argument("--encoder-counts", type=int, default=None, metavar="N",
                   help="encoder resolution (counts/rev) of a node without object 0x2003 "
                        "sub 11 (default: the EDS default, 16384)")
    prog = p.add_mutually_exclusive_group()
    prog.add_argument("--progress", dest="progress", action="store_true", default=None,
                      help="show a progress bar (default: on a terminal, runs over 2 s)")
    prog.add_argument("--no-progress", dest="progress", action="store_false")
    g = p.add_argument_group("profile parameters")
    for kw, flag in _profile_flags().items():
        g.add_argument(flag, dest=f"pf_{kw}", type=float, default=None, metavar="X",
                       help=argparse.SUPPRESS)
    opt.add_bus(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """`bench run`: every input checked before anything starts; SIGINT/SIGTERM end the
    run with its partial trace saved and its log closed (exit 128 + signal number)."""
    from bench.bus import bus_settings
    from bench.ecu import Interrupted, StopSignal, run_over_bus

    profile = _checked_profile(args)
    duration = args.duration if args.duration is not None else profile.duration_s
    progress = args.progress
    if progress is None:
        progress = sys.stderr.isatty() and duration >= 2.0

    def say(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    from plant_rt.pacing import use_normal_priority, use_realtime_priority
    sched = use_realtime_priority(args.rt_priority)
    if args.rt_priority:
        say(f"scheduling: {sched}")
    stop = StopSignal()
    with stop.installed():
        try:
            trace = run_over_bus(profile, assignments=args.assignments, pace=args.pace,
                                 duration_s=args.duration, log_path=args.log,
                                 progress=progress, settings=bus_settings(args),
                                 start_plant=not args.no_plant, node_id=args.node_id,
                                 announce=say, spin_us=args.spin_us, stop=stop,
                                 encoder_counts=args.encoder_counts, serial=args.serial,
                                 stamp=args.stamp)
        except BenchError as exc:
            stop.defer = True       # a second signal must not cut the partial trace's save
            msg = _ended(exc, args)
            if isinstance(exc, Interrupted):
                print(f"error: {msg}", file=sys.stderr)
                return 128 + exc.signum
            raise BenchError(msg) from None
        finally:
            use_normal_priority()
        stop.defer = True
        trace.meta["scheduling"] = sched
        if args.save:
            try:
                trace.save(args.save)
            except OSError as exc:
                raise BenchError(f"cannot write the trace {args.save}: "
                                 f"{exc.strerror or exc}; the run itself completed") from None
        print(summary(trace, args.save))
        if stop.signum is not None:    # the signal came as the run ended: it is complete
            print(f"error: interrupted by {signal.Signals(stop.signum).name} at the end of "
                  f"a complete run ({len(trace)} periods)", file=sys.stderr)
            return 128 + stop.signum
    return 0


MAX_DURATION_S = 1e15
"""The longest --duration (its SYNC periods still count as an integer; the memory check
refuses a run far shorter, saying how long one can be)."""
MAX_TRAVEL_M = 10.0
"""No set-point beyond this (`plant_rt.params` caps the plant's travel limit there)."""


def _check_frequency(kwargs: dict) -> None:
    """A profile's set-point frequencies (--frequency-hz, --f0-hz, --f1-hz) a set-point can
    hold under the shortest SYNC period a node takes (`sim.sync_period_s`); the run checks
    them again under the node's own period once it has read it (`run_over_bus`)."""
    from bench.profiles.setpoints import check_sampled
    from plant_rt.params import resolve
    lo = resolve("sim.sync_period_s").min
    check_sampled(kwargs, float(lo if lo is not None else 1e-4), "the shortest a node takes")


def _checked_profile(args: argparse.Namespace):
    """The run's profile, after every flag and output path is checked (BenchError)."""
    from bench.profiles.catalog import make_profile, profile_args
    from bench.signals.trace import check_save_path, probe_output

    kwargs = {k[3:]: v for k, v in vars(args).items() if k.startswith("pf_") and v is not None}
    if args.duration is not None:
        if not (math.isfinite(args.duration) and 0 < args.duration <= MAX_DURATION_S):
            raise BenchError(f"--duration must be > 0 s and at most {MAX_DURATION_S:g} s")
        if "duration_s" in profile_args(args.profile):
            kwargs["duration_s"] = args.duration
    for k, v in kwargs.items():
        if isinstance(v, float) and not math.isfinite(v):
            raise BenchError(f"--{k.replace('_', '-')} must be a finite number, not {v}")
    _check_frequency(kwargs)
    amp = kwargs.get("amplitude_m")
    if amp is not None and abs(amp) > MAX_TRAVEL_M:
        raise BenchError(f"--amplitude-m {amp:g} m: beyond any actuator's travel (the "
                         f"plant's travel limit is at most {MAX_TRAVEL_M:g} m); the set-point "
                         "would be clamped")
    profile = make_profile(args.profile, **kwargs)
    if args.save:
        check_save_path(args.save)
    if args.log:
        from bench.bus.logwrite import log_format
        probe_output(args.log, "log")
        log_format(args.log, "--log")
    if not 0 <= args.spin_us <= 1000:
        raise BenchError("--spin-us must be within 0..1000 us")
    if not 0 <= args.rt_priority <= 99:
        raise BenchError("--rt-priority must be within 0..99")
    return profile


def _ended(exc: BenchError, args: argparse.Namespace) -> str:
    """Save the partial trace of a failed run (`--save`); the one-line message saying
    how far it went and where the partial results are."""
    partial = getattr(exc, "trace", None)
    if partial is None or not len(partial):
        return f"{exc}; no period done" if getattr(exc, "signum", None) else str(exc)
    msg = f"{exc}; {len(partial)} periods done"
    if args.log:
        msg += f", log up to there in {args.log}"
    if args.save:
        try:
            partial.save(args.save)
            msg += f", partial trace in {args.save}"
        except (OSError, BenchError) as err:
            msg += f", partial trace NOT saved ({err})"
    return msg


def summary(trace, save: str | None = None) -> str:
    """A few lines describing a bus run."""
    m = trace.meta
    ecu = m.get("ecu", {})
    n = len(trace)
    sim = n * trace.dt if n > 1 else 0.0
    wall = ecu.get("wall_s", float("nan"))
    lines = [f"run {m.get('profile')} over {m.get('bus')}, pace {m.get('pace')}",
             f"  {n} periods ({sim:.3f} s simulated) in {wall:.2f} s wall: "
             f"{sim / wall if wall else float('nan'):.2f}x real time"]
    pos, sp = trace["position_m"], trace["setpoint_position_m"]
    if n:
        if int(trace["mode"][0]) == 1:
            lines.append(f"  final position {pos[-1] * 1e3:.3f} mm (set-point "
                         f"{sp[-1] * 1e3:.3f} mm), peak |current| "
                         f"{np.nanmax(np.abs(trace['current_a'])):.2f} A")
        else:
            lines.append(f"  final motor speed {trace['motor_speed_rad_s'][-1]:.2f} rad/s "
                         f"(set-point {trace['setpoint_speed_rad_s'][-1]:.2f} rad/s), peak "
                         f"|current| {np.nanmax(np.abs(trace['current_a'])):.2f} A")
    pc = m.get("plant_counters", {})
    if pc and "error" not in pc:
        lines.append(f"  plant: {pc['frames_received']} frames received, {pc['bad_frames']} bad, "
                     f"{pc['unknown_frames']} unknown, {pc['demands_invalid']} invalid demands, "
                     f"{pc['rpdo_missing']} RPDO missing, {pc['deadline_misses']} deadline "
                     f"misses, jitter p50/p99/max {pc['jitter_p50_us']:.0f}/"
                     f"{pc['jitter_p99_us']:.0f}/{pc['jitter_max_us']:.0f} us")
    if m.get("pace") == "realtime":
        if m.get("scheduling"):
            lines.append(f"  scheduling of the ECU (and of a hub and plant started for "
                         f"the run): {m['scheduling']}")
        lines.append(f"  ECU SYNC jitter p50/p99/max {ecu.get('sync_jitter_p50_us', 0):.0f}/"
                     f"{ecu.get('sync_jitter_p99_us', 0):.0f}/"
                     f"{ecu.get('sync_jitter_max_us', 0):.0f} us, "
                     f"{ecu.get('sync_deadline_misses', 0)} deadline misses, "
                     f"{ecu.get('late_tpdo', 0)} late TPDO sets")
    if n and "status_word" in trace:
        from ema_contract.states import StatusWord
        words = np.nan_to_num(trace["status_word"]).astype(np.int64)
        seen = [f"{str(b.name).lower()} in {int(np.count_nonzero(words & int(b)))} periods"
                for b in (StatusWord.OVERCURRENT, StatusWord.END_OF_STROKE,
                          StatusWord.OVERTEMPERATURE) if (words & int(b)).any()]
        if seen:
            lines.append("  plant conditions (reported, the run stays valid): "
                         + ", ".join(seen))
    if ecu.get("sdo_retries"):
        lines.append(f"  SDO: {ecu['sdo_retries']} transfers started again after an answer "
                     f"came later than the SDO timeout ({ecu.get('sdo_stray_answers', 0)} "
                     "late answers dropped)")
    em = m.get("emcy", [])
    if em:
        c = Counter(e["name"] for e in em)
        lines.append(f"  EMCY: {len(em)} (" + ", ".join(f"{k} x{v}" for k, v in c.items())
                     + ")")
    else:
        lines.append("  EMCY: none")
    if m.get("log"):
        lines.append(f"  log: {m['log']} ({ecu.get('frames_logged', 0)} frames)")
    if save:
        lines.append(f"  trace: {save}")
    return "\n".join(lines)
