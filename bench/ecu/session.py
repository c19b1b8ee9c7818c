"""A bus run from end to end: bus, plant, claim, set-up, run, log (`run_over_bus`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

from bench import BenchError
from bench.bus.logwrite import log_format
from bench.ecu.errors import PlantLost
from bench.ecu.master import Ecu
from bench.ecu.nodeinfo import NodeInfo
from bench.ecu.rtcheck import RealtimeCheck, realtime_check
from bench.ecu.runloop import run_periods
from bench.ecu.signals import StopSignal
from bench.profiles.catalog import Profile
from bench.profiles.setpoints import check_sampled
from bench.signals.trace import Trace, probe_output
from bench.sim.control import ControllerParams
from ema_contract.states import Pace
from plant_rt.params import ParameterError, PlantParams, check_value, resolve


def plant_values(profile: Profile, assignments: list[str] | None = None,
                 values: dict[str, Any] | None = None) -> dict[str, Any]:
    """Parameter settings for a run: the profile's own (e.g. the RUL schedule), then
    `values`, then ``NAME=VALUE`` assignments; checked here (BenchError if invalid)."""
    out: dict[str, Any] = dict(profile.params_overrides)
    out.update(values or {})
    for a in assignments or []:
        if "=" not in a:
            raise BenchError(f"--set expects NAME=VALUE, got {a!r}")
        k, v = a.split("=", 1)
        out[k.strip()] = v.strip()
    try:
        PlantParams().with_dict(out)
    except ParameterError as exc:
        raise BenchError(str(exc)) from None
    return out


def setting_origins(profile: Profile, assignments: list[str] | None = None,
                    values: dict[str, Any] | None = None) -> dict[str, str]:
    """Canonical parameter name -> where the run's setting of it comes from (for
    messages): ``profile NAME``, ``values`` or ``--set`` (the last one wins, as in
    `plant_values`)."""
    out: dict[str, str] = {}
    items = [(k, f"profile {profile.name}") for k in profile.params_overrides]
    items += [(k, "values") for k in (values or {})]
    items += [(a.split("=", 1)[0].strip(), "--set") for a in assignments or [] if "=" in a]
    for name, source in items:
        try:
            out[resolve(name).name] = source
        except ParameterError:
            pass
    return out


def _with_node(trace: Trace | None, info: NodeInfo) -> Trace | None:
    """`trace` with what the ECU found on the node (``meta["node"]``); the parameters in
    ``meta["params"]`` only when the node gave them all; ``meta["actuator_serial"]`` the
    serial number of 0x1018 sub 4, "unknown" when the node has none."""
    if trace is not None:
        node = asdict(info)
        if info.params_complete:
            del node["params"]           # all of them are in meta["params"]
        else:
            trace.meta.pop("params", None)
        trace.meta["node"] = node
        serial = info.identity.get("serial")
        trace.meta["actuator_serial"] = "unknown" if serial is None else str(serial)
    return trace


def _check_run(profile: Profile, vals: dict[str, Any], duration_s: float | None,
               log_path: str | Path | None, encoder_counts: int | None) -> None:
    """Before anything starts: `encoder_counts`, the run's length and the log path (its
    format from the suffix: `bench.bus.logwrite.LOG_FORMATS`)."""
    if encoder_counts is not None:
        try:
            check_value(resolve("sensors.encoder_counts_per_rev"), encoder_counts)
        except ParameterError as exc:
            raise BenchError(f"--encoder-counts: {exc}") from None
    run_periods(profile.duration_s if duration_s is None else duration_s,
                PlantParams().with_dict(vals).sim.sync_period_s)
    if log_path:
        probe_output(log_path, "log")
        log_format(log_path)


def _find_plant(ecu: Ecu, sess: Any, start_plant: bool, pace: Pace | None,
                node_id: int | None, say: Callable[[str], None],
                serial: int | None = None) -> None:
    """Wait for the node on the session's bus; when none answers on a simulated bus and
    `start_plant`, start a plant process for the run (stopped with the session)."""
    from bench.bus import is_simulated
    from bench.bus.procs import start_plant as _start_plant
    try:
        ecu.wait_for_plant(1.0 if sess.children else 0.6)
        if serial is not None:
            say(f"serial number {serial} not applied: a node already answers (its own "
                "serial is in the trace; start a plant with `bench up --serial N`)")
    except PlantLost:
        ecu.check_receive()
        if not (start_plant and is_simulated(sess.cfg)):
            raise PlantLost(f"no actuator node 0x{ecu.node_id:02X} answering on "
                            f"{sess.description}") from None
        pace = Pace.REALTIME if pace is None else pace
        say(f"starting a plant for this run (pace {pace.name.lower()})")
        sess.children.append(_start_plant(sess.cfg, pace=pace.name.lower(),
                                          node_id=node_id, serial=serial))


def _set_up(ecu: Ecu, pace: Pace | None, vals: dict[str, Any], spin_us: int,
            origin: dict[str, str], encoder_counts: int | None, sync_driven: bool,
            say: Callable[[str], None]) -> tuple[PlantParams, Pace, RealtimeCheck | None]:
    """`Ecu.prepare`, what it found said; in real time the pacer's calibration. Returns
    the parameters, the run's pace and the calibration (None in lockstep)."""
    params = ecu.prepare(pace, vals, spin_us, origin=origin, encoder_counts=encoder_counts,
                         sync_driven=sync_driven)
    run_pace = ecu.run_pace or Pace.REALTIME
    say(ecu.pace_source)
    for note in ecu.node_info.notes:
        say(note)
    check = None
    if run_pace == Pace.REALTIME:
        check = realtime_check(ecu, params.sim.sync_period_s, spin_us)
        say(check.message())
    return params, run_pace, check


def run_over_bus(profile: Profile, values: dict[str, Any] | None = None,
                 assignments: list[str] | None = None, pace: Pace | str | None = Pace.SYNC,
                 duration_s: float | None = None, log_path: str | Path | None = None,
                 progress: bool = False, settings: dict[str, Any] | None = None,
                 start_plant: bool = True, cparams: ControllerParams | None = None,
                 node_id: int | None = None, announce: Callable[[str], None] | None = None,
                 echo: bool = False, spin_us: int = 200, encoder_counts: int | None = None,
                 sync_driven: bool = False, stop: StopSignal | None = None,
                 serial: int | None = None, stamp: str = "bus") -> Trace:
    """Run `profile` against the plant over the bus and return the trace.

    The bus is the configured one (flags in `settings`, environment, config file,
    vcan0, the hub of `bench up`), else a private loopback hub started for this run.
    When no plant answers on a simulated bus (hub, virtual, vcan) and `start_plant`,
    a plant process is started for the run. Everything started here is stopped here.

    A node without the simulated plant's optional objects (a real actuator,
    docs/node-contract.md) is run with what it has: `announce` is told what is missing
    and what the ECU does instead, and ``trace.meta["node"]`` records it (`NodeInfo`);
    ``meta["params"]`` is then left out, since the ECU does not know the node's
    parameters. `encoder_counts` (counts/rev) stands in for a missing encoder
    resolution object; `sync_driven` vouches that a node without the lockstep object
    steps one period per SYNC, so that `pace` "sync" may run against it; `pace` None
    follows the node (its own pace, `Ecu.prepare`; real time for a plant started here, and
    a real-time run starts with a short calibration, `bench.ecu.rtcheck`). `serial` is the
    serial number (0x1018 sub 4) of the plant started for the run, if one is. `stamp`:
    the log's time stamps, "bus" (lockstep: SYNC count x period) or "wall" (`Ecu.run`).

    Before anything starts: the run's length (`run_periods`) and the log path are
    checked. Before any NMT command or SDO write: `Ecu.claim` (no other ECU on the node).
    On error the partial trace is in the exception's ``trace`` attribute, the log is
    closed and the node, once claimed, is set PRE-OPERATIONAL (`Ecu.abort`)."""
    from bench.bus import close_bus, connect, session

    want = (None if pace is None else
            Pace[pace.upper()] if isinstance(pace, str) else Pace(pace))
    if stamp not in ("bus", "wall"):
        raise BenchError(f"stamp must be 'bus' or 'wall', not {stamp!r}")
    vals = plant_values(profile, assignments, values)
    origin = setting_origins(profile, assignments, values)
    _check_run(profile, vals, duration_s, log_path, encoder_counts)
    say = announce or (lambda s: None)
    with session(settings) as sess:
        bus = connect(sess.cfg, receive_own_messages=echo)
        ecu = None
        try:
            ecu = Ecu(bus, node_id=node_id, log_path=log_path, echo=echo)
            _find_plant(ecu, sess, start_plant, want, node_id, say, serial)
            say(f"bus {sess.description}")
            ecu.claim(say)
            ecu.start_heartbeat()
            params, run_pace, check = _set_up(ecu, want, vals, spin_us, origin,
                                              encoder_counts, sync_driven, say)
            check_sampled(profile.kwargs, params.sim.sync_period_s, "the node's")
            ecu.check_foreign(" during set-up")
            ecu.check_receive(" during set-up")
            trace = ecu.run(profile, params, cparams, run_pace, duration_s, progress,
                            spin_us=spin_us, stop=stop, stamp=stamp)
            if check is not None:
                trace.meta["realtime_check"] = asdict(check)
            if ecu.log is not None:     # the last frames reach the disk, or the run fails
                ecu.log.close()
                ecu.log.raise_error(" at the end of the run")
            _with_node(trace, ecu.node_info)
            trace.meta["ecu"]["sdo_retries"] = ecu.sdo_retries
            trace.meta["ecu"]["sdo_stray_answers"] = ecu.remote.sdo.stray
            trace.meta["bus"] = sess.description
            if log_path:
                trace.meta["log"] = str(log_path)
            return trace
        except BaseException as exc:
            if ecu is not None:
                ecu.abort()
                if isinstance(exc, (BenchError, KeyboardInterrupt)):
                    exc.trace = _with_node(ecu.partial, ecu.node_info)  # type: ignore[union-attr]
            raise
        finally:
            if ecu is not None:
                ecu.close()
            close_bus(bus)
