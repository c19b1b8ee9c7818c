"""`bench fleet synth`: a synthetic fleet of ground-test logs, N actuators x D days.

Each actuator's wear follows the thesis' run-to-failure schedule (section 6.5,
`plant_rt.params.ScheduleParams`: preload falling linearly to zero, backlash and friction
growing as (e^(g s) - 1)/(e^g - 1) to 100 um and x4 at the end of life) with its rates and
start preload drawn from the campaign's ranges (`bench.hums.campaign.CAMPAIGN_RANGES`).
Where the actuator is on that schedule on day d, its position s in [0, 1], is set by one
of two rules (`wear=`):

- ``use`` (the default): **wear driven by use**. Each actuator draws its utilisation
  (`UTILISATION`: mean flights per day, mean flight severity) and a life budget B (a
  Weibull draw of shape `BUDGET_WEIBULL_SHAPE` with median 1, the spread of rolling-bearing
  lives). Each day it flies Poisson(flights per day) flights at that day's severity (its
  mean x U(0.8, 1.2)). The life one flight consumes is measured, not assumed: the bench's
  usage monitor (`bench.usage.usage_of_trace`, ISO 3408-5 L10 with Palmgren-Miner) on the
  seeded `flight` profile (30 s, `load.kind=aero`, fast plant mode) simulated ONCE per
  synth for each severity of `SEVERITY_GRID` (`flight_life_table`; cached by severity)
  and interpolated log-log in between. The day's consumption c_d (fraction of L10) is
  flights x that per-flight life. Day d's ground test comes before that day's flights,
  so s_d = K x (c_0 + ... + c_(d-1)) / B, held at 1 past the end of life. K is the time
  compression (`compression`): one synthetic day must stand for many real ones for an
  actuator to wear out in a window of D days, so K is set such that an actuator of
  nominal use (`NOMINAL_FLIGHTS_PER_DAY` flights a day at severity 1) and budget 1 reaches
  s = 1 after `NOMINAL_LIFE_FRAC` x D days. **The link from consumed L10 life to the
  schedule's s (linear in consumption, the end of life at consumption B / K) is a
  modelling choice of this synthetic fleet, not a thesis result**: the thesis' schedule
  is in time; it gives no mapping from rating life to preload, backlash and friction.
- ``time``: the previous rule, wear in time: the actuator's life in days is drawn
  uniformly between LIFE_DAYS_FRAC x D and day d is the schedule at s = d / life.

The ground test each day is the thesis' health-check sine (H4: 0.5 mm, 2 Hz,
GROUND_TEST_CYCLES periods, position loop, no load) with sensor noise, simulated
in-process (`bench.sim.harness.simulate`, the bench's own closed loop; no bus) and written as
a candump log through the DBC, the frames a lockstep bus run logs (NMT start, then per
SYNC period: SYNC, set-point, TPDO1-3, RPDO1), so an ingest of the synthetic fleet reads
logs by the same path as a real rig's. Candump rather than trace tables: the fleet's real
input is the ECU's log, and the decoder is most of its cost. The ground test carries no
load, so the usage the ingest stores from these logs is the ground test's own (~0), not
the flights' (which are not logged).

Layout: ``OUT/<actuator>/<YYYY-MM-DDTHH-MM-SS>.log`` (the actuator id is the directory
name, `bench.fleet.ingest.actuator_id`) and ``OUT/fleet-truth.json``: each actuator's
drawn schedule, utilisation, budget, per-day flights, consumption and s, and its end of
life (the first day s reaches 1), so a RUL can be checked against the truth it never saw
(`bench.fleet.truthcheck`).
"""

from __future__ import annotations

import datetime as dt
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench import BenchError
from bench.signals.trace import Trace
from ema_contract.frames import Frames
from ema_contract.states import ControlWord, NMTCommand, StatusWord

GROUND_TEST_CYCLES = 4.0
"""Periods of the daily ground-test sine (the thesis' H4 run has 4: 2 s at 2 Hz)."""
LIFE_DAYS_FRAC = (0.6, 4.0)
"""`wear="time"`: an actuator's life in days, as a fraction of the synthetic window D:
some reach their end of life inside the window, most do not."""
EPOCH = dt.datetime(2026, 1, 5, tzinfo=dt.UTC)
"""Day 0 of a synthetic fleet (a Monday)."""
SCHEDULE_FIELDS = ("schedule.backlash_growth", "schedule.friction_growth",
                   "schedule.preload_start_n", "schedule.preload_zero_frac")
WEAR_RULES = ("use", "time")

# --- use-driven wear: the utilisation draws, data with units and sources ------------------
UTILISATION = {
    # name: (low, high, unit, source or reason); each drawn uniformly per actuator
    "flights_per_day": (2.0, 8.0, "1/day",
                        "chosen: short- to medium-haul rotations, 2-8 sectors a flight day"),
    "severity": (0.7, 1.4, "-",
                 "the usage campaign's mean flight severity (bench.hums.usage_campaign)"),
}
SEVERITY_DAY = (0.8, 1.2)
"""Day-to-day factor on the actuator's mean severity, uniform (-): the usage campaign's."""
SEVERITY_GRID = (0.5, 0.75, 1.0, 1.25, 1.5, 1.75)
"""Severities (-) the flight is simulated at once per synth; covers 0.7 x 0.8 .. 1.4 x 1.2."""
FLIGHT_S = 30.0
"""Simulated flight (s): the usage campaign's `flight` profile length; one stands for a
flight (its life consumed is per flight; the compression K absorbs real flight length)."""
FLIGHT_SEED = 11
"""Seed of the simulated flight (profile and gusts): the same flight at every severity."""
BUDGET_WEIBULL_SHAPE = 1.5
"""Spread of the life budget B (Weibull shape, median 1): ISO 281's life modification
factor a1 rests on a Weibull shape of 1.5 for rolling bearings."""
NOMINAL_FLIGHTS_PER_DAY = 5.0
"""Nominal use (1/day, at severity 1): the middle of UTILISATION's flights per day."""
NOMINAL_LIFE_FRAC = 1.5
"""Chosen: an actuator of nominal use and budget 1 reaches its end of life after this x D
days (the compression K follows), so some actuators fail inside the window, most not."""

_LIFE_TABLE: dict[float, float] = {}


@dataclass(frozen=True)
class Actuator:
    """One synthetic actuator: its id, its schedule's draws, its ground test's hour and,
    under use-driven wear, its utilisation, budget and per-day truth."""
    ident: str
    life_days: float
    schedule: dict[str, float]
    hour_utc: float
    utilisation: dict[str, float] = field(default_factory=dict)
    budget: float = math.nan
    flights: tuple[int, ...] = ()
    severity_day: tuple[float, ...] = ()
    consumed: tuple[float, ...] = ()
    s: tuple[float, ...] = ()


def flight_life_table(grid: tuple[float, ...] | None = None) -> dict[float, float]:
    """Life consumed (fraction of L10, Palmgren-Miner) by one simulated flight at each
    severity of `grid`: the `flight` profile under the aero load, usage by `bench.usage`.
    Simulated once per severity per process (cached); `grid` defaults to SEVERITY_GRID."""
    from bench.profiles.catalog import make_profile
    from bench.sim.harness import simulate
    from bench.usage import usage_of_trace
    from plant_rt.params import PlantParams
    grid = SEVERITY_GRID if grid is None else grid
    for sev in grid:
        if sev not in _LIFE_TABLE:
            p = PlantParams().with_dict({
                "load.kind": "aero", "load.gust_seed": FLIGHT_SEED,
                "sensors.noise_seed": FLIGHT_SEED, "drive.pwm_mode": "averaged",
                "sim.ball_model": "quasistatic"})
            tr = simulate(make_profile("flight", duration_s=FLIGHT_S, severity=sev,
                                       seed=FLIGHT_SEED), p)
            _LIFE_TABLE[sev] = float(usage_of_trace(tr, params=p).life_consumed)
    return {s: _LIFE_TABLE[s] for s in grid}


def life_per_flight(severity: np.ndarray, table: dict[float, float]) -> np.ndarray:
    """Per-flight life consumed at `severity`, log-log interpolated in `table` (clamped
    to its severity range)."""
    sev = np.array(sorted(table))
    life = np.log([table[s] for s in sev])
    x = np.clip(np.asarray(severity, dtype=float), sev[0], sev[-1])
    return np.exp(np.interp(np.log(x), np.log(sev), life))


def compression(days: int, table: dict[float, float]) -> float:
    """Time compression K: nominal use with budget 1 ends its life after
    NOMINAL_LIFE_FRAC x `days` days (module docstring)."""
    nominal = NOMINAL_FLIGHTS_PER_DAY * float(life_per_flight(np.array([1.0]), table)[0])
    return 1.0 / (nominal * NOMINAL_LIFE_FRAC * days)


def use_days(util: dict[str, float], budget: float, days: int, k: float,
             table: dict[float, float], rng: np.random.Generator
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One actuator's days: flights, severity, life consumed (fraction of L10, not
    compressed) and the schedule position s of each day's ground test (before its
    flights): s_d = K sum_(j<d) c_j / B, at most 1."""
    flights = rng.poisson(util["flights_per_day"], days)
    sev = util["severity"] * rng.uniform(*SEVERITY_DAY, days)
    consumed = flights * life_per_flight(sev, table)
    s = np.minimum(k * np.concatenate([[0.0], np.cumsum(consumed)[:-1]]) / budget, 1.0)
    return flights, sev, consumed, s


def draw_fleet(n: int, days: int, seed: int, wear: str = "use") -> list[Actuator]:
    """The fleet's actuators (ids EMA-0000...), each with its own draws. The schedule,
    time-rule life and hour come from the stream [seed, k] as before use-driven wear;
    the utilisation, budget and days from [seed, k, 1]."""
    from bench.hums.campaign import CAMPAIGN_RANGES
    if wear not in WEAR_RULES:
        raise BenchError(f"wear must be one of {', '.join(WEAR_RULES)}, got {wear!r}")
    table = flight_life_table() if wear == "use" else {}
    k_comp = compression(days, table) if wear == "use" else math.nan
    out = []
    for k in range(n):
        rng = np.random.default_rng([seed, k])
        life = float(rng.uniform(*LIFE_DAYS_FRAC)) * days
        sched = {f: float(rng.uniform(*CAMPAIGN_RANGES[f])) for f in SCHEDULE_FIELDS}
        act = Actuator(f"EMA-{k:04d}", life, sched, float(rng.uniform(5.0, 9.0)))
        if wear == "use":
            r2 = np.random.default_rng([seed, k, 1])
            util = {u: float(r2.uniform(lo, hi)) for u, (lo, hi, *_) in UTILISATION.items()}
            budget = float(r2.weibull(BUDGET_WEIBULL_SHAPE)) / math.log(2.0) ** (
                1.0 / BUDGET_WEIBULL_SHAPE)
            fl, sev, cons, s = use_days(util, budget, days, k_comp, table, r2)
            act = Actuator(act.ident, end_of_life_day(s), sched, act.hour_utc, util, budget,
                           tuple(int(x) for x in fl), tuple(sev.tolist()),
                           tuple(cons.tolist()), tuple(s.tolist()))
        out.append(act)
    return out


def end_of_life_day(s: np.ndarray) -> float:
    """The first day whose ground test is at s = 1 (the schedule's end of life), or inf."""
    hit = np.flatnonzero(np.asarray(s) >= 1.0)
    return float(hit[0]) if len(hit) else math.inf


def schedule_pos(act: Actuator, day: int) -> float:
    """The actuator's schedule position s on `day` (module docstring)."""
    if act.s:
        return act.s[min(day, len(act.s) - 1)]
    return min(day / act.life_days, 1.0)


def wear_at(act: Actuator, day: int) -> dict[str, float]:
    """The actuator's preload, backlash and friction scale on `day` (section 6.5's
    schedule at s = `schedule_pos`, `plant_rt.model.schedule_at`)."""
    from plant_rt.model import schedule_at
    from plant_rt.params import PlantParams
    p = PlantParams().with_dict({"schedule.kind": "rul", "schedule.duration_s": 1.0,
                                 **act.schedule})
    pre, b, f = schedule_at(p, schedule_pos(act, day))
    return {"effects.preload_n": pre, "effects.backlash_m": b, "effects.friction_scale": f}


def _job(job: tuple[str, dict[str, float], int, float, str]) -> str:
    """Worker: one ground test simulated and written as a candump log."""
    from bench.profiles.catalog import sine
    from bench.sim.harness import simulate
    from plant_rt.params import PlantParams
    from plant_rt.paramvalues import seed_in_range
    path, wear, noise_seed, t0, _ = job
    p = PlantParams().with_dict({**wear, "sensors.noise": True,
                                 "sensors.noise_seed": seed_in_range(noise_seed)})
    tr = simulate(sine(cycles=GROUND_TEST_CYCLES), p)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    write_candump(tr, path, t0)
    return path


def truth_of(fleet: list[Actuator], n: int, days: int, seed: int, wear: str) -> dict:
    """The truth file's content (module docstring)."""
    truth: dict = {"seed": seed, "actuators": n, "days": days, "epoch": EPOCH.isoformat(),
                   "ground_test": f"sine 0.5 mm 2 Hz x {GROUND_TEST_CYCLES:g}", "wear": wear}
    rows = []
    for a in fleet:
        row: dict = {"actuator": a.ident, "hour_utc": a.hour_utc, **a.schedule}
        if wear == "use":
            eol = a.life_days
            row.update(utilisation=a.utilisation, budget=a.budget,
                       end_of_life_day=eol if math.isfinite(eol) else None,
                       flights=list(a.flights), severity=a.severity_day,
                       life_consumed=a.consumed, s=a.s)
        else:
            row.update(life_days=a.life_days,
                       s=[schedule_pos(a, d) for d in range(days)])
        rows.append(row)
    if wear == "use":
        table = flight_life_table()
        truth["use"] = {
            "utilisation": {k: {"low": v[0], "high": v[1], "unit": v[2], "source": v[3]}
                            for k, v in UTILISATION.items()},
            "severity_day": list(SEVERITY_DAY), "flight_s": FLIGHT_S,
            "flight_seed": FLIGHT_SEED,
            "life_per_flight": {f"{k:g}": v for k, v in table.items()},
            "compression": compression(days, table),
            "budget_weibull_shape": BUDGET_WEIBULL_SHAPE,
            "nominal_flights_per_day": NOMINAL_FLIGHTS_PER_DAY,
            "nominal_life_frac": NOMINAL_LIFE_FRAC,
            "mapping": "s_d = compression x sum(life_consumed[:d]) / budget, at most 1; "
                       "a modelling choice of the synthetic fleet, not a thesis result"}
    truth["fleet"] = rows
    return truth


LOG_BYTES = 532_036
"""Bytes of one ground test's candump log (2000 SYNC periods x 6 frames), measured;
`tests/unit/test_fleet_limits.py` checks it against a log written."""
MEMORY_PER_LOG = 2048
"""Bytes of this process's memory per log: ~650 measured (tracemalloc: the fleet's
draws, the jobs and the truth file), x3 for the tasks' copies and the results."""


def check_size(n: int, days: int, out_dir: str | Path) -> None:
    """BenchError, before anything is written, when n x days logs cannot fit: their
    bytes (LOG_BYTES each) on the disk of `out_dir`, or their bookkeeping
    (MEMORY_PER_LOG each) in half the memory available now."""
    import shutil

    from bench.signals.trace import memory_available
    logs = n * days
    base = Path(out_dir).absolute()
    while not base.exists() and base != base.parent:
        base = base.parent
    free = shutil.disk_usage(base).free
    need = logs * LOG_BYTES
    if need > free:
        raise BenchError(f"--actuators {n} --days {days}: {logs} logs of ~{LOG_BYTES / 1e3:.0f} "
                         f"kB need ~{_size(need)}; the disk of {base} has {_size(free)} free "
                         f"(at most ~{free // LOG_BYTES} logs)")
    room = memory_available() // 2
    if logs * MEMORY_PER_LOG > room:
        raise BenchError(f"--actuators {n} --days {days}: {logs} logs need ~"
                         f"{_size(logs * MEMORY_PER_LOG)} of memory to plan and track; half "
                         f"the memory available is {_size(room)} (at most ~"
                         f"{room // MEMORY_PER_LOG} logs per command)")


def _size(b: float) -> str:
    for unit, k in (("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if b >= k:
            return f"{b / k:.3g} {unit}"
    return f"{b / 1e3:.3g} kB"


def synth(n: int, days: int, out_dir: str | Path, seed: int = 0, workers: int | None = None,
          progress: bool = True, scheduler: str | None = None, wear: str = "use"
          ) -> list[Path]:
    """Write the fleet's logs (n x days) and, once they are all written, its truth file;
    returns the log paths. Refused before anything is written when they cannot fit
    (`check_size`) or the scheduler does not answer; an actuator's folder is made with
    its first log."""
    if n < 1 or days < 1:
        raise BenchError("the synthetic fleet needs at least one actuator and one day")
    check_size(n, days, out_dir)
    from bench.runtime.cluster import probe_scheduler, scheduler_address
    addr = scheduler_address(scheduler)
    if addr is not None:
        probe_scheduler(addr)
    out = Path(out_dir)
    fleet = draw_fleet(n, days, seed, wear)
    jobs = []
    for k, act in enumerate(fleet):
        for d in range(days):
            when = EPOCH + dt.timedelta(days=d, seconds=round(act.hour_utc * 3600.0))
            path = out / act.ident / f"{when:%Y-%m-%dT%H-%M-%S}.log"
            jobs.append((str(path), wear_at(act, d), int(seed * 1_000_003 + k * 10_007 + d),
                         when.timestamp(), act.ident))
    truth = truth_of(fleet, n, days, seed, wear)
    check_out(out, truth, {Path(j[0]) for j in jobs})
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BenchError(f"{out}: cannot create the output directory: {exc}") from None
    from bench.fleet.ingest import run_jobs
    got = run_jobs(_job, jobs, workers, progress, scheduler, desc="fleet synth", unit="log",
                   label=lambda job: str(job[0]))
    (out / "fleet-truth.json").write_text(json.dumps(truth, indent=1))
    return [Path(p) for p in got]


_SETTINGS = ("seed", "actuators", "days", "wear")


def check_out(out: Path, truth: dict, paths: set[Path]) -> None:
    """BenchError, before anything is written, when OUT holds what this fleet is not: the
    truth file of a fleet drawn with other settings, or logs it would not write (a rig's,
    another fleet's). The same fleet written again, or resumed, passes."""
    if not out.is_dir():
        return
    old = out / "fleet-truth.json"
    if old.exists():
        try:
            had = json.loads(old.read_text())
            was = {k: had[k] for k in _SETTINGS}
        except (OSError, ValueError, TypeError, KeyError):
            raise BenchError(f"{old}: not a fleet-truth.json of `bench fleet synth`: give "
                             "an empty folder") from None
        if any(was[k] != truth[k] for k in _SETTINGS):
            raise BenchError(
                f"{out} holds another synthetic fleet (seed {was['seed']}, "
                f"{was['actuators']} actuators x {was['days']} days, wear {was['wear']}): "
                "give an empty folder, or its own --seed, --actuators, --days and --wear "
                "to write it again")
    foreign = next((p for p in out.rglob("*.log") if p not in paths), None)
    if foreign is not None:
        raise BenchError(f"{out} holds logs this fleet would not write ({foreign}): give "
                         "an empty folder")


# --- the candump writer ------------------------------------------------------------------

def write_candump(tr: Trace, path: str | Path, t0: float, node_id: int | None = None) -> None:
    """`tr` (a harness trace) as the candump -L log a lockstep bus run of it gives: NMT
    start, then per SYNC period SYNC, ECU set-point, TPDO1-3 (the sensors at that SYNC)
    and RPDO1 (the demand), every value clamped to its DBC range and encoded through the
    DBC (`Frames.codec`: cantools' encoding, vectorised), the lines as python-can's
    CanutilsLogWriter writes them."""
    from plant_rt.params import PlantParams
    fr = Frames(node_id)
    pp = PlantParams()
    period = float(tr.meta.get("period_s") or pp.sim.sync_period_s)
    n = len(tr)

    def col(name: str, default: float = 0.0) -> np.ndarray:
        return np.nan_to_num(np.asarray(tr[name], dtype=float)) if name in tr \
            else np.full(n, default)

    angle = col("motor_angle_rad")
    values = {  # frame -> signal -> per-period values (offset of the frame in its period)
        "SYNC": {"SYNC_Counter": np.arange(n) % 240 + 1.0},
        "ECU_Setpoint": {"SetpointPosition": col("setpoint_position_m"),
                         "SetpointSpeed": col("setpoint_speed_rad_s"), "Mode": col("mode")},
        "EMA_TPDO1": {"MotorCurrent": col("current_a"),
                      "StatusWord": np.full(n, float(StatusWord.ENABLED))},
        "EMA_TPDO2": {"EncoderAngle": np.round(angle * pp.sensors.encoder_counts_per_rev
                                               / (2.0 * math.pi)),
                      "EncoderSpeed": col("motor_speed_rad_s")},
        "EMA_TPDO3": {"LvdtPosition": col("position_m"),
                      "WindingTemperature": col("temperature_k", 300.0),
                      "LoadForce": col("load_force_n")},
        "EMA_RPDO1": {"CurrentDemand": col("current_demand_a"),
                      "ControlWord": np.full(n, float(ControlWord.ENABLE))},
    }
    offsets = {"SYNC": 0.0, "ECU_Setpoint": 50e-6, "EMA_TPDO1": 100e-6, "EMA_TPDO2": 110e-6,
               "EMA_TPDO3": 120e-6, "EMA_RPDO1": 300e-6}
    for name, sig in values.items():
        for s, v in sig.items():
            spec = fr.by_name[name].get_signal_by_name(s)
            lo = -math.inf if spec.minimum is None else spec.minimum
            hi = math.inf if spec.maximum is None else spec.maximum
            sig[s] = np.clip(v, lo, hi)
    start = fr.encode_unchecked("NMT", {"NMT_Command": int(NMTCommand.START),
                                        "NMT_NodeId": fr.node_id})
    head = f"({t0 - period:.6f}) can0 {start.arbitration_id:03X}#{start.data.hex().upper()} T\n"
    base = t0 + np.arange(n) * period            # each period's SYNC time, as t0 + k * period
    body = _candump_body(fr, values, offsets, base)
    try:
        Path(path).write_text(head + body)
    except OSError as exc:
        raise BenchError(f"{path}: cannot write the log: {exc}") from None


_ASCII_HEX = np.frombuffer(b"0123456789ABCDEF", dtype=np.uint8)


def _candump_body(fr: Frames, values: dict[str, dict[str, np.ndarray]],
                  offsets: dict[str, float], base: np.ndarray) -> str:
    """The log's lines after the NMT start: per period, each frame of `values` in order
    at ``base + offset``, its payload encoded through the DBC (`Frames.codec`, what
    cantools' encode gives, to the bit). Built as one character table per frame kind
    (every line of a kind has the same width) when the time stamps allow it
    (`_stamp_chars`), else line by line; the text is the same."""
    n = len(base)
    kinds = []
    for name, sig in values.items():
        payload = _payloads(fr, name, sig, n)
        hexed = np.empty((n, 2 * payload.shape[1]), dtype=np.uint8)
        hexed[:, 0::2] = _ASCII_HEX[payload >> 4]
        hexed[:, 1::2] = _ASCII_HEX[payload & 0x0F]
        kinds.append((f") can0 {fr.cob[name]:03X}#", base + offsets[name], hexed))
    stamps = [_stamp_chars(t) for _, t, _ in kinds]
    if n == 0:
        return ""
    ready = [st for st in stamps if st is not None]
    if len(ready) < len(stamps):
        mids = [mid for mid, _, _ in kinds]
        times = [t.tolist() for _, t, _ in kinds]
        texts = [[h.tobytes().decode("ascii") for h in hexed] for _, _, hexed in kinds]
        return "".join(f"({times[i][k]:.6f}{mids[i]}{texts[i][k]} T\n"
                       for k in range(n) for i in range(len(kinds)))

    def const(text: str) -> np.ndarray:
        return np.broadcast_to(np.frombuffer(text.encode("ascii"), dtype=np.uint8),
                               (n, len(text)))

    parts = []
    for (mid, _, hexed), st in zip(kinds, ready, strict=True):
        parts += [const("("), st, const(mid), hexed, const(" T\n")]
    return np.concatenate(parts, axis=1).tobytes().decode("ascii")


def _payloads(fr: Frames, name: str, sig: dict[str, np.ndarray], n: int) -> np.ndarray:
    """The payloads (uint8, one row per period) of frame `name` with these signal
    values: the DBC's vectorised codec, or cantools frame by frame without one."""
    codec = fr.codec(name)
    if codec is not None:
        return codec.encode(sig)
    m = fr.by_name[name]
    rows = [m.encode({s: float(v[k]) for s, v in sig.items()}, strict=False) for k in range(n)]
    return np.frombuffer(b"".join(rows), dtype=np.uint8).reshape(n, m.length)


def _stamp_chars(t: np.ndarray) -> np.ndarray | None:
    """``f"{x:.6f}"`` of each time stamp as a table of ASCII characters, or None when it
    cannot be made exactly so (a stamp under 2**20 s or from 2**33 s on, or stamps of
    different widths). Exact: for 2**20 <= x < 2**33, x - floor(x) has at most 32
    fractional bits, so (x - floor(x)) * 1e6 is computed without rounding, and rounding
    it half to even is what Python's formatting does."""
    if not len(t) or not np.all(np.isfinite(t)) or t.min() < 2.0 ** 20 or t.max() >= 2.0 ** 33:
        return None
    whole = np.floor(t)
    micros = whole.astype(np.int64) * 1_000_000 + np.rint((t - whole) * 1e6).astype(np.int64)
    width = len(str(int(micros.max())))
    if len(str(int(micros.min()))) != width:
        return None
    digits = np.empty((len(t), width + 1), dtype=np.uint8)
    rest = micros.copy()
    for j in [*range(width, width - 6, -1), *range(width - 7, -1, -1)]:
        digits[:, j] = rest % 10 + ord("0")
        rest //= 10
    digits[:, width - 6] = ord(".")
    return digits
