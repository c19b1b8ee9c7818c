"""`bench fleet synth`: a synthetic fleet of ground-test logs, N actuators x D days.

Each actuator has its own wear: the thesis' run-to-failure schedule (section 6.5,
`plant_rt.params.ScheduleParams`: preload falling linearly to zero, backlash and
friction growing as (e^(g s) - 1)/(e^g - 1) to 100 um and x4 at the end of life) with
its rates and start preload drawn from the campaign's ranges
(`bench.hums.campaign.CAMPAIGN_RANGES`) and its own life in days, drawn uniformly
between LIFE_DAYS_FRAC x D. Day d of an actuator of life L is the schedule at s = d / L
(held at the end of life past it). Its ground test that day is the thesis' health-check
sine (H4: 0.5 mm, 2 Hz, GROUND_TEST_CYCLES periods, position loop) with sensor noise,
simulated in-process (`bench.harness.simulate`, the bench's own closed loop; no bus)
and written as a candump log through the DBC, the frames a lockstep bus run logs
(NMT start, then per SYNC period: SYNC, set-point, TPDO1-3, RPDO1), so an ingest of the
synthetic fleet reads logs by the same path as a real rig's. Candump rather than trace
tables: the fleet's real input is the ECU's log, and the decoder is most of its cost.

Layout: ``OUT/<actuator>/<YYYY-MM-DDTHH-MM-SS>.log`` (the actuator id is the directory
name, `bench.fleet.ingest.actuator_id`) and ``OUT/fleet-truth.json``: each actuator's
drawn schedule and life, so a RUL can be checked against the truth it never saw.
"""

from __future__ import annotations

import datetime as dt
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench import BenchError
from bench.trace import Trace
from ema_contract.frames import Frames
from ema_contract.states import ControlWord, NMTCommand, StatusWord

GROUND_TEST_CYCLES = 4.0
"""Periods of the daily ground-test sine (the thesis' H4 run has 4: 2 s at 2 Hz)."""
LIFE_DAYS_FRAC = (0.6, 4.0)
"""An actuator's life in days, as a fraction of the synthetic window D: some reach
their end of life inside the window, most do not."""
EPOCH = dt.datetime(2026, 1, 5, tzinfo=dt.UTC)
"""Day 0 of a synthetic fleet (a Monday)."""
SCHEDULE_FIELDS = ("schedule.backlash_growth", "schedule.friction_growth",
                   "schedule.preload_start_n", "schedule.preload_zero_frac")


@dataclass(frozen=True)
class Actuator:
    """One synthetic actuator: its id, its life in days and its schedule's draws."""
    ident: str
    life_days: float
    schedule: dict[str, float]
    hour_utc: float


def draw_fleet(n: int, days: int, seed: int) -> list[Actuator]:
    """The fleet's actuators (ids EMA-0000...), each with its own draws."""
    from bench.hums.campaign import CAMPAIGN_RANGES
    out = []
    for k in range(n):
        rng = np.random.default_rng([seed, k])
        life = float(rng.uniform(*LIFE_DAYS_FRAC)) * days
        sched = {f: float(rng.uniform(*CAMPAIGN_RANGES[f])) for f in SCHEDULE_FIELDS}
        out.append(Actuator(f"EMA-{k:04d}", life, sched, float(rng.uniform(5.0, 9.0))))
    return out


def wear_at(act: Actuator, day: int) -> dict[str, float]:
    """The actuator's preload, backlash and friction scale on `day` (section 6.5's
    schedule at s = day / life, `plant_rt.model.schedule_at`)."""
    from plant_rt.model import schedule_at
    from plant_rt.params import PlantParams
    p = PlantParams().with_dict({"schedule.kind": "rul", "schedule.duration_s": 1.0,
                                 **act.schedule})
    pre, b, f = schedule_at(p, min(day / act.life_days, 1.0))
    return {"effects.preload_n": pre, "effects.backlash_m": b, "effects.friction_scale": f}


def _job(job: tuple[str, dict[str, float], int, float, str]) -> str:
    """Worker: one ground test simulated and written as a candump log."""
    from bench.harness import simulate
    from bench.profiles import sine
    from plant_rt.params import PlantParams
    path, wear, noise_seed, t0, _ = job
    p = PlantParams().with_dict({**wear, "sensors.noise": True,
                                 "sensors.noise_seed": noise_seed})
    tr = simulate(sine(cycles=GROUND_TEST_CYCLES), p)
    write_candump(tr, path, t0)
    return path


def synth(n: int, days: int, out_dir: str | Path, seed: int = 0, workers: int | None = None,
          progress: bool = True, scheduler: str | None = None) -> list[Path]:
    """Write the fleet's logs (n x days) and its truth file; returns the log paths."""
    if n < 1 or days < 1:
        raise BenchError("the synthetic fleet needs at least one actuator and one day")
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BenchError(f"{out}: cannot create the output directory: {exc}") from None
    fleet = draw_fleet(n, days, seed)
    jobs = []
    for k, act in enumerate(fleet):
        (out / act.ident).mkdir(exist_ok=True)
        for d in range(days):
            when = EPOCH + dt.timedelta(days=d, seconds=round(act.hour_utc * 3600.0))
            path = out / act.ident / f"{when:%Y-%m-%dT%H-%M-%S}.log"
            jobs.append((str(path), wear_at(act, d), int(seed * 1_000_003 + k * 10_007 + d),
                         when.timestamp(), act.ident))
    truth = {"seed": seed, "actuators": n, "days": days, "epoch": EPOCH.isoformat(),
             "ground_test": f"sine 0.5 mm 2 Hz x {GROUND_TEST_CYCLES:g}",
             "fleet": [{"actuator": a.ident, "life_days": a.life_days,
                        **a.schedule} for a in fleet]}
    (out / "fleet-truth.json").write_text(json.dumps(truth, indent=1))
    from bench.fleet.ingest import run_jobs
    got = run_jobs(_job, jobs, workers, progress, scheduler, desc="fleet synth", unit="log")
    return [Path(p) for p in got]


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
