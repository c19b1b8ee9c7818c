"""Fault signatures of one cycle against a healthy baseline, all on the standardised
residual of `baseline.residuals`.

The stroke features (localised, level, periodic, turn) read the current less the cycle's
median dwell current (`baseline.standstill_current`: the drive's current steps by itself
between cycles); the dwell feature reads the logged current, the index feature the phase
indexes of the current against the standstill. Each stroke is cut in two
(`travel_start`): its take-up of the reversal (from the reversal to where the healthy
position error has settled, `takeup_window`, from the baseline alone) and its travel.

- localised (position-locked): a spall on the screw gives a current transient at the
  same nut position on every pass. Each stroke's travel residual, less its constant in
  amperes (`zone_free`: a level shift is not localised), is scanned with windows of
  `SCALES` samples (the window's sum over sqrt(width): unit variance under the
  baseline's noise); so is the sum of the out- and in-stroke residuals at the same
  set-point position (the nut passes the same place in both directions). The score is
  the largest |scan|; its window gives the position in mm of travel (measured position,
  not set-point) and the width.
- level: friction raises the current in both directions: the mean of the out- and
  in-stroke travel residuals (each stroke's own kept for the naming: `naming`).
- reversal (backlash as a hysteresis): a play of width b makes the nut trail the motor by
  b/2 against the motion, so the position error shifts by +b/2 on the out-stroke and
  -b/2 on the in-stroke, the current unchanged. Each stroke's position-error residual
  after its acceleration ramp gives its weighted least-squares constant (`constant`);
  the score is |d_out - d_in| over its standard error.
- takeup (lost motion at a reversal): while a stroke takes up the reversal the motor
  turns through a play before the nut follows: the position-error residual's constant
  over the take-up, along the motion, over its standard error, per stroke (the sensor's
  zero, the dwells' median error, removed); the score is the larger of the two strokes,
  since a one-sided load shows the play at one reversal only, which one its sign decides.
- hysteresis (backlash as a hysteresis over the take-ups): the two strokes' take-up
  constants along the motion added, over its standard error (`hysteresis`): a position
  offset that moves between runs cancels, a lag at both reversals (or at the one a
  one-sided load leaves a play on) remains.
- turn: the current residual's constant over each take-up over its standard error (a
  breakaway friction and a play's free run both move it), the larger of the two.
- periodic (position-periodic, at the screw's lead): a defect on the screw's raceway
  passes under the nut's balls once per screw revolution, i.e. once per lead of travel.
  The travel residual of each stroke (`zone_free`, then less its mean) is projected on
  cos/sin of 2 pi x / lead at the measured positions x (no resampling);
  2 |sum z e^(-i theta)|^2 / N is chi-square with 2 degrees of freedom under the
  baseline's noise, and the score is the sum over both strokes. Where: the same
  projection over a sliding window of `PERIODIC_WINDOW` samples, out- and in-stroke
  added at the same position, its largest value.
- rattle (a play's broadband roughness along the stroke, `rattle.roughness`): the
  rougher stroke's; naming-only (`NAMING_ONLY`), as the hysteresis is.
- play (a play's weak signatures together, `play.play_score`): the hysteresis, the reversal,
  the take-up and the rattle each as its excess over its own threshold, added; it needs
  the thresholds, so `assess` computes it, and its own threshold comes from the same
  leave-one-run-out healthy scores as every other (`population.thresholds`);
  naming-only.
- dwell (standstill): the current and position-error residuals of each dwell, less their
  medians, scanned as the localised feature scans a stroke; the score is the largest
  |scan|.
- index: each phase index of the cycle (`baseline.phase_indexes(referenced=True)`: mean,
  RMS and peak current against the standstill, mean and peak position error, the current
  of the ramps) against the baseline's mean and predictive spread of a new run's cycle
  (`baseline.ref_indexes`, within and between runs); the score is the largest |z|, and
  the index it came from is kept.

Where (`location`): a spall confined to one spot of the raceway acts over about a nut
length of travel, so a located effect (periodic or localised) is placed where the
localised scan of the strokes is strongest (windows up to 27 samples, about 26 mm at the
Cranfield stroke speed), and only when that scan is above its threshold; the sliding
periodic projection's maximum is kept beside it (`periodic_mm`), but a line that runs
along the whole stroke has no place of its own.

`assess` flags a cycle when any feature is above its threshold and names its signature
and the fault family it points to (`naming.attribute`); `rig_verdict` is the verdict
(`verdict.RigVerdict`): the signature with its place or its index, every other feature
above its threshold, the baseline used, and whether it is provisional.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from bench.core.verdict import Level, Verdict
from bench.rig import kernels as K
from bench.rig.baseline import (
    Baseline,
    LoadBaseline,
    incomplete,
    phase_indexes,
    residuals,
    standstill_error,
)
from bench.rig.cycles import Cycle
from bench.rig.offsets import is_offset, position_shifts, shift_text
from bench.rig.play import PLAY, hysteresis, play_score
from bench.rig.rattle import roughness
from bench.rig.verdict import RigVerdict, provisional_note

SCALES = (1, 3, 9, 27)          # scan window widths, samples
_SCALES = np.asarray(SCALES, dtype=np.int64)
PERIODIC_WINDOW = 25            # samples of the sliding periodic projection (~24 mm)
STROKE_CURRENT = "current_ref_a"   # the stroke features' current (against the standstill)
FEATURES = ("localised", "level", "reversal", "takeup", "hysteresis", "turn", "periodic",
            "dwell", "index", "rattle", "play")
SPECIFIC = ("periodic", "localised")
NAMING_ONLY = ("hysteresis", "rattle", "play")
"""Features that name a flagged cycle's fault but flag none (no share of the false-alarm
rate is split off for them)."""
EFFECTS = {
    "dwell": "a transient at standstill (in a dwell)",
    "index": "a phase index outside its healthy spread",
    "periodic": "position-periodic effect at the screw's lead (once per revolution)",
    "localised": "localised (position-locked) effect",
    "level": "friction-like effect (current raised in both directions)",
    "drag": "drag lowered in both directions (less friction, or the preload's drag lost)",
    "reversal": "backlash-like effect (position error at the reversals)",
    "takeup": "backlash-like effect (lost motion at a reversal: the position error while "
              "the motion reverses)",
    "hysteresis": "backlash-like effect (position-error hysteresis: the lag while taking "
                  "up both reversals changed alike along the motion)",
    "turn": "the current while the motion reverses (a breakaway friction or a play's "
            "impact: the current alone cannot tell which)",
    "rattle": ("backlash-like effect (the current rough along the whole travel: a nut "
               "moving within a play as the drive's force ripples)"),
    "play": ("backlash-like effect (a play's weak signatures together: the take-up "
             "hysteresis, the reversal, the lost motion and the rattle, none of them alone "
             "need be above its threshold)"),
    "offset": ("position offset in every phase, backlash-like under a one-sided load (a "
               "play held on one flank by the load, a nut softer under the load, or a "
               "moved position-sensor zero)"),
}


@dataclass
class CycleFeatures:
    """The features of one cycle and where its localised effect is."""
    label: str
    source: str
    load: float
    run: int
    group: int
    scores: dict[str, float]
    location_mm: float          # centre of the strongest localised window
    width_mm: float
    where: str                  # out, in or both (the profile the window is in)
    out_mm: float               # strongest window of each stroke alone
    in_mm: float
    level_out: float
    level_in: float
    periodic_mm: float = float("nan")     # where the lead-periodic residual is largest
    periodic_out_mm: float = float("nan")
    periodic_in_mm: float = float("nan")
    index_at: str = ""                    # the phase and index of the largest index |z|
    # per phase: the cycle's mean position error less the baseline's mean of it (mm)
    position_shift_mm: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    incomplete: str = ""                  # why the cycle cannot be judged ("" it can)
    reversal_signed: float = float("nan")  # (d_out - d_in) / se, the reversal score's sign
    # the position-error change while each stroke takes up the reversal (mm), and its
    # significance: the side a one-sided load leaves a play on shows, the other does not
    takeup_mm: dict[str, float] = field(default_factory=dict)
    takeup_z: dict[str, float] = field(default_factory=dict)
    turn_z: dict[str, float] = field(default_factory=dict)   # the current in the take-up
    hysteresis_signed: float = float("nan")   # the take-ups' common lag over its se

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def scan(z: np.ndarray) -> tuple[float, int, int]:
    """The largest |window sum / sqrt(width)| over `SCALES`: (score, centre index, width)
    (NaN samples count 0; compiled: `kernels.scan`)."""
    s, k, w = K.scan(np.asarray(z, dtype=np.float64), _SCALES)
    return float(s), int(k), int(w)


def _mean(x: np.ndarray) -> float:
    """`np.mean` of a 1-D float64 array, bit for bit (`kernels.psum`); NaN when empty."""
    return float(K.psum(x)) / len(x) if len(x) else float("nan")


def _strokes(res: dict[str, tuple[np.ndarray, np.ndarray]]
             ) -> tuple[tuple[np.ndarray, np.ndarray] | None, tuple[np.ndarray, np.ndarray] | None]:
    return res.get("out"), res.get("in")


def _matched(lb: LoadBaseline, z_in: np.ndarray) -> np.ndarray:
    """The in-stroke residual at the out-stroke's set-point positions (nearest aligned
    sample within half a set-point step; 0 where none)."""
    idx, ok = lb.memo(f"matched.{len(z_in)}", lambda: _match(lb, len(z_in)))
    return np.where(ok, z_in[idx], 0.0)


def _match(lb: LoadBaseline, n_in: int) -> tuple[np.ndarray, np.ndarray]:
    """`_matched`'s picks from the baseline's set-points alone: (the in-stroke sample of
    each out-stroke sample, whether it lies within half a set-point step)."""
    sp_out, sp_in = lb.phases["out"].setpoint_mm, lb.phases["in"].setpoint_mm[:n_in]
    step = float(np.median(np.abs(np.diff(sp_out)))) if len(sp_out) > 1 else 1.0
    order = np.argsort(sp_in)
    j = np.clip(np.searchsorted(sp_in[order], sp_out), 0, len(order) - 1)
    j0 = np.clip(j - 1, 0, len(order) - 1)
    pick = np.where(np.abs(sp_in[order][j0] - sp_out) < np.abs(sp_in[order][j] - sp_out),
                    j0, j)
    idx = order[pick]
    return idx, np.abs(sp_in[idx] - sp_out) <= 0.5 * step + 1e-9


def periodic(z: np.ndarray, pos: np.ndarray, lead_mm: float
             ) -> tuple[float, np.ndarray]:
    """(2 |sum z e^(-i 2 pi x / lead)|^2 / N over the stroke, the same over a sliding
    window of `PERIODIC_WINDOW` samples at each sample (NaN where it does not fit))."""
    z = z - _mean(z)
    e = z * np.exp(-2j * np.pi * pos / lead_mm)
    whole = float(2.0 * abs(e.sum()) ** 2 / len(z)) if len(z) else float("nan")
    w = min(PERIODIC_WINDOW, len(z))
    local = np.full(len(z), np.nan)
    if w >= 3:
        c = np.concatenate((np.zeros(1, dtype=e.dtype), np.cumsum(e)))
        vals = 2.0 * np.abs(c[w:] - c[:-w]) ** 2 / w
        local[w // 2: w // 2 + len(vals)] = vals
    return whole, local


def _periodic(res: dict[str, tuple[np.ndarray, np.ndarray]], lead_mm: float | None
              ) -> tuple[float, float, float, float]:
    """(score, where both strokes agree best, out-stroke alone, in-stroke alone)."""
    nan = float("nan")
    if not lead_mm or "out" not in res or "in" not in res:
        return nan, nan, nan, nan
    (zo, po), (zi, pi) = res["out"], res["in"]
    so, lo = periodic(zo, po, lead_mm)
    si, li = periodic(zi, pi, lead_mm)
    order = np.argsort(pi)
    ok = np.isfinite(li[order])
    both = lo + (np.interp(po, pi[order][ok], li[order][ok], left=np.nan, right=np.nan)
                 if ok.sum() > 1 else np.nan)

    def at(prof: np.ndarray, pos: np.ndarray) -> float:
        return float(pos[int(K.nanargmax(prof))]) if np.isfinite(prof).any() else nan

    return so + si, at(both, po), at(lo, po), at(li, pi)


def cycle_features(lb: LoadBaseline, cycle: Cycle, lead_mm: float | None = None
                   ) -> CycleFeatures:
    """The features of `cycle` against the baseline of its load (periodic only with the
    screw's lead)."""
    sig = stroke_signal(lb)
    cache: dict[str, Any] = {}
    res = _residuals(lb, cycle, sig, cache)
    out, inn = _strokes(res)
    notes: list[str] = []
    nan = float("nan")
    loc: tuple[float, float, float, str] = (0.0, nan, nan, "-")   # score, mm, width, where
    side = {"out": nan, "in": nan}
    levels = {"out": nan, "in": nan}
    turn: dict[str, float] = {}                 # the current while taking up a reversal
    profiles: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    masked: dict[str, np.ndarray] = {}          # the travel's profile, 0 in the take-up
    rough: list[float] = []                     # each stroke's travel roughness (`rattle`)
    for name, r in (("out", out), ("in", inn)):
        if r is None:
            notes.append(f"no {name}-stroke in the cycle or the baseline")
            continue
        z, pos = r
        std = lb.phases[name].std[sig][:len(z)]
        w = travel_start(lb, name, len(z))
        levels[name] = _mean(z[w:])
        zt = zone_free(std[w:], z[w:])
        profiles[name] = (zt, pos[w:])
        masked[name] = np.r_[np.zeros(w), zt]
        rough.append(roughness(z[w:] * std[w:], std[w:], pos[w:], lead_mm))
        if w >= 2:
            c, se = constant(std[:w] * math.sqrt(1.0 + 1.0 / lb.n), z[:w])
            turn[name] = c / se
    if out is not None and inn is not None:
        both = (masked["out"][:len(lb.phases["out"])] + _matched(lb, masked["in"])
                [:len(masked["out"])]) / math.sqrt(2.0)
        profiles["both"] = (both, out[1][:len(both)])
    for name, (z, pos) in profiles.items():
        s, k, w = scan(z)
        if name in side:
            side[name] = float(pos[min(k, len(pos) - 1)])
        if s > loc[0]:
            step = float(K.median(np.abs(np.diff(pos)))) if len(pos) > 1 else nan
            loc = (s, float(pos[min(k, len(pos) - 1)]), w * step, name)
    level = (float(np.nanmean([levels["out"], levels["in"]]))
             if np.isfinite([levels["out"], levels["in"]]).any() else nan)
    per = _periodic({k: profiles[k] for k in ("out", "in") if k in profiles}, lead_mm)
    pidx = phase_indexes(cycle)                 # read by the shifts
    idx, idx_at = index_score(lb, phase_indexes(cycle, referenced=True) if lb.ref_indexes
                              else pidx)
    rev = _reversal(lb, cycle, cache)
    take_mm, take_z = takeup(lb, cycle, cache)
    scores = {"localised": loc[0], "level": abs(level), "reversal": abs(rev),
              "takeup": max((abs(v) for v in take_z.values()), default=nan),
              "hysteresis": abs(hyst := hysteresis(take_mm, take_z)),
              "turn": max((abs(v) for v in turn.values()), default=nan),
              "periodic": per[0], "dwell": dwell_score(lb, cycle, cache), "index": idx,
              "rattle": max((v for v in rough if math.isfinite(v)), default=nan)}
    if lead_mm is None:
        notes.append("periodic: not available (the screw's lead was not given)")
    return CycleFeatures(cycle.label, cycle.source, cycle.load, cycle.run, cycle.group,
                         scores, loc[1], loc[2], loc[3],
                         side["out"], side["in"], levels["out"], levels["in"],
                         per[1], per[2], per[3], idx_at, position_shifts(lb, pidx),
                         notes, incomplete(lb, cycle), rev, take_mm, take_z, turn, hyst)


def stroke_signal(lb: LoadBaseline) -> str:
    """The current the stroke features read: against the cycle's standstill
    (`current_ref_a`) when the baseline keeps it (older baselines: the logged current)."""
    ph = next(iter(lb.phases.values()), None)
    return STROKE_CURRENT if ph is not None and STROKE_CURRENT in ph.mean else "current_a"


def _residuals(lb: LoadBaseline, cycle: Cycle, sig: str, cache: dict[str, Any] | None
               ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """`baseline.residuals`, once per signal within one cycle's features (`cache`)."""
    if cache is None:
        return residuals(lb, cycle, sig)
    if sig not in cache:
        cache[sig] = residuals(lb, cycle, sig)
    return cache[sig]  # type: ignore[no-any-return]


def dwell_score(lb: LoadBaseline, cycle: Cycle, cache: dict[str, Any] | None = None
                ) -> float:
    """The largest |scan| of the dwells' current and position-error residuals (each less
    its median); NaN when neither the cycle nor the baseline has a dwell."""
    best = float("nan")
    for sig in ("current_a", "position_error_mm"):
        for name, (z, _) in _residuals(lb, cycle, sig, cache).items():
            if lb.phases[name].direction == 0 and len(z) >= 3:
                s = scan(z - K.median(z))[0]
                best = s if not math.isfinite(best) else max(best, s)
    return best


def index_score(lb: LoadBaseline, indexes: dict[str, dict[str, float]]
                ) -> tuple[float, str]:
    """(the largest |z| of a cycle's phase `indexes` against the baseline's, "phase index"
    where it is); NaN without indexes. With the baseline's referenced indexes
    (`LoadBaseline.ref_indexes`: `indexes` then come from `phase_indexes(referenced=
    True)`) z is over the predictive spread of a cycle of a new run (within and between
    runs); an older baseline's raw indexes are over their spread times sqrt(1 + 1/n)."""
    ref = bool(lb.ref_indexes)
    table = lb.ref_indexes if ref else lb.indexes
    infl = 1.0 if ref else math.sqrt(1.0 + 1.0 / lb.n)
    best, at = float("nan"), ""
    for phase, vals in indexes.items():
        for key, v in vals.items():
            m, sd = table.get(phase, {}).get(key, (nan_, nan_))
            if not (math.isfinite(v) and math.isfinite(m) and sd > 0):
                continue
            z = abs(v - m) / (sd * infl)
            if not math.isfinite(best) or z > best:
                best, at = z, f"{phase} {key}"
    return best, at


def constant(std: np.ndarray, z: np.ndarray, start: int = 0) -> tuple[float, float]:
    """A phase residual's weighted least-squares constant in the signal's own unit (over
    the baseline's inflated spread), from aligned sample `start` on: (constant, its
    standard error under the baseline's noise). z_k = c u_k + noise, u_k = 1 / spread_k."""
    c, se = K.constant(np.asarray(std, dtype=np.float64), np.asarray(z, dtype=np.float64),
                       start)
    return float(c), float(se)


def travel_start(lb: LoadBaseline, stroke: str, n: int) -> int:
    """The first aligned sample of a stroke's travel: after its take-up of the reversal
    (`takeup_window`), leaving at least `MIN_TRAVEL` of its `n` samples."""
    return max(0, min(window(lb, stroke), n - MIN_TRAVEL))


def window(lb: LoadBaseline, stroke: str) -> int:
    """`takeup_window` of the baseline's stroke, once per baseline."""
    ps = lb.phases[stroke]
    return int(lb.memo(f"takeup.{stroke}", lambda: takeup_window(ps)))


MIN_TRAVEL = 27          # samples of travel a stroke keeps at least (the widest scan)


def zone_free(std: np.ndarray, z: np.ndarray) -> np.ndarray:
    """A zone's residual less its weighted constant in the signal's unit: a friction torque
    is a constant current on a stroke, which divided by the per-sample spread is not a
    constant in z and would leak into the localised scan and the periodic projection."""
    if not len(z):
        return z
    c, _ = constant(std, z)
    return z - c / std[:len(z)]


def _reversal(lb: LoadBaseline, cycle: Cycle, cache: dict[str, Any] | None = None
              ) -> float:
    """Backlash as a hysteresis: (d_out - d_in) / its standard error, d a stroke's
    position-error constant after its acceleration ramp (module doc); the score is its
    magnitude."""
    sig = "position_error_mm"
    res = _residuals(lb, cycle, sig, cache)
    segs = {g.name: g for g in cycle.segments()}
    d: dict[str, tuple[float, float]] = {}
    for n in ("out", "in"):
        if n not in res or n not in segs or not len(res[n][0]):
            return float("nan")
        start = cycle.ramps(segs[n])["accel"].stop - segs[n].start
        d[n] = constant(lb.phases[n].std[sig], res[n][0], start)
    return (d["out"][0] - d["in"][0]) / math.hypot(d["out"][1], d["in"][1])


SETTLED = 0.1
"""A reversal's take-up lasts until the healthy mean position error has fallen below this
share of its peak after the stroke starts."""


def takeup_window(ps: Any) -> int:
    """The aligned samples of a stroke's take-up of the reversal, from the healthy
    baseline alone: from the stroke's start to where the baseline's mean position error
    has settled on its plateau (the median of the stroke's second half) to `SETTLED` of
    its largest departure from it; 0 when that departure is within 3 per-sample spreads
    (no transient to take up)."""
    e = ps.mean["position_error_mm"]
    if len(e) < 4:
        return 0
    dev = np.abs(e - float(np.median(e[len(e) // 2:])))
    k = int(np.argmax(dev))
    if dev[k] <= 3.0 * float(np.median(ps.std["position_error_mm"])):
        return 0
    low = np.flatnonzero(dev[k:] < SETTLED * dev[k])
    return int(k + low[0]) if len(low) else len(e)


def _zero(lb: LoadBaseline, sig: str) -> float:
    """The baseline's median position error in its dwells (its sensor zero)."""
    dwell = [p.mean[sig] for p in lb.phases.values() if p.direction == 0 and len(p)]
    return float(np.median(np.concatenate(dwell))) if dwell else 0.0


def takeup(lb: LoadBaseline, cycle: Cycle, cache: dict[str, Any] | None = None
           ) -> tuple[dict[str, float], dict[str, float]]:
    """Lost motion at each reversal: per stroke, the position-error residual's weighted
    constant over the take-up (`takeup_window`), in mm along the motion (a play the motor
    turns through before the nut follows adds to the lag, so + is more lag), and the
    same over its standard error. A one-sided load holds the nut on one flank of a play
    and the play shows at one reversal only; which one the load's sign decides, so the
    score is the larger of the two."""
    sig = "position_error_mm"
    res = _residuals(lb, cycle, sig, cache)
    mm: dict[str, float] = {}
    zz: dict[str, float] = {}
    # the position sensor's zero as the cycle and as the baseline see it (the dwells'
    # median error): a zero that moves between runs is not a lost motion
    zero = standstill_error(cycle) - lb.memo("standstill_error", lambda: _zero(lb, sig))
    infl = math.sqrt(1.0 + 1.0 / lb.n)
    for n in ("out", "in"):
        if n not in res or not len(res[n][0]):
            continue
        ps = lb.phases[n]
        w = min(window(lb, n), len(res[n][0]))
        if w < 2:
            continue
        std = ps.std[sig][:w] * infl
        c, se = constant(std, res[n][0][:w] - zero / std)
        mm[n] = float(c * ps.direction)
        zz[n] = float(c / se * ps.direction)
    return mm, zz


@dataclass(frozen=True)
class Judgement:
    """A cycle against its thresholds: flagged or not, the signature named (an `EFFECTS`
    key, "none" when nothing is above), the fault family it points to
    (`naming.FAULTS`, "" when not flagged) and every feature against its threshold."""
    flagged: bool
    effect: str
    fault: str
    reasons: list[str]
    ratios: dict[str, float]


def assess(f: CycleFeatures, thresholds: dict[str, float]) -> Judgement:
    """The cycle judged: flagged when any feature but a naming-only one (`NAMING_ONLY`)
    is above its threshold; the fault family and its signature from `naming.attribute` (the family whose strongest
    signature is furthest above its threshold; friction and backlash both above and
    neither clearly ahead: indistinguishable). A level below the healthy one in both
    directions is `drag` (the preload's drag lost: backlash-like), an index that is a
    mean position error moved alike in every phase `offset`."""
    from bench.rig import naming
    scores = f.scores
    if PLAY in thresholds:
        scores = {**scores, PLAY: play_score(scores, thresholds)}
    ratios = {k: scores[k] / thresholds[k] for k in FEATURES
              if k in thresholds and math.isfinite(scores.get(k, nan_))
              and thresholds[k] > 0}
    above = {k: r for k, r in ratios.items() if r > 1.0}
    reasons = [f"{k} {scores[k]:.2f} vs threshold {thresholds[k]:.2f}" for k in ratios]
    if not set(above) - set(NAMING_ONLY):
        return Judgement(False, "none", "", reasons, ratios)
    fault, effect = naming.attribute(above, naming.level_sign(f.level_out, f.level_in),
                                     "index" in above and is_offset(f))
    return Judgement(True, effect, fault, reasons, ratios)


def judge(f: CycleFeatures, thresholds: dict[str, float], reference: str = "") -> Verdict:
    """`assess` as a verdict: DEGRADED with the signature named when flagged, else
    HEALTHY; judged against `reference` (the baseline the thresholds come from)."""
    j = assess(f, thresholds)
    return Verdict(Level.DEGRADED if j.flagged else Level.HEALTHY, j.effect, tuple(j.reasons),
                   reference)


FEATURE_OF = {"drag": "level", "offset": "index"}   # effects named by another feature
nan_ = float("nan")


def verdict(base: Baseline, f: CycleFeatures, thresholds: dict[str, float]) -> dict[str, Any]:
    """The verdict of one cycle (`rig_verdict`) as a dict (`RigVerdict.to_dict`)."""
    return rig_verdict(base, f, thresholds).to_dict()


def rig_verdict(base: Baseline, f: CycleFeatures, thresholds: dict[str, float]
                ) -> RigVerdict:
    """The verdict of one cycle: flagged or not, the signature and the fault family,
    where (for a located one), the scores against their thresholds, and the baseline
    used (provisional with fewer than 3 healthy runs, and then said in the text). An
    incomplete cycle is not judged (level UNKNOWN) and says why."""
    from bench.rig import naming
    lb = base.for_load(f.load)
    prov = lb.provisional
    if f.incomplete:
        return RigVerdict(level=Level.UNKNOWN, effect="not judged", cycle=f.label,
                          text=f"not judged: {f.incomplete}", reference=base.describe(f.load),
                          provisional=prov)
    j = assess(f, thresholds)
    where = location(f, j.effect, thresholds) if j.flagged else None
    if not j.flagged:
        text = "no significant deviation from the healthy baseline"
    else:
        text = f"{naming.TEXT[j.fault]}: {effect_text(f, j.effect, where, thresholds)}"
        named = FEATURE_OF.get(j.effect, j.effect)
        others = [k for k in FEATURES if k != named and j.ratios.get(k, 0.0) > 1.0]
        if others:
            text += "; also above threshold: " + ", ".join(others)
    if prov:
        text += f"; {provisional_note(len(set(lb.runs)))}"
    return RigVerdict(level=Level.DEGRADED if j.flagged else Level.HEALTHY, effect=j.effect,
                      reasons=tuple(j.reasons), reference=base.describe(f.load),
                      cycle=f.label, fault=j.fault, text=text, provisional=prov,
                      location_mm=where)


def effect_text(f: CycleFeatures, effect: str, where: float | None,
                thresholds: dict[str, float]) -> str:
    """The words on the signature named: where a located one is, which index, which
    reversal took up a play."""
    if effect == "periodic" and where is None:
        return (f"{EFFECTS[effect]}; spread along the stroke, not located (the localised "
                f"scan {f.scores['localised']:.2f} is below its threshold "
                f"{thresholds.get('localised', nan_):.2f}; the lead-periodic projection is "
                f"largest at {f.periodic_mm:.1f} mm)")
    if effect == "localised":
        agree = (abs(f.out_mm - f.in_mm) if math.isfinite(f.out_mm + f.in_mm) else nan_)
        return (f"{EFFECTS[effect]} at {f.location_mm:.1f} mm of travel "
                f"({'both strokes' if f.where == 'both' else f.where + '-stroke'}, "
                f"about {f.width_mm:.0f} mm wide; out-stroke alone {f.out_mm:.1f} mm, "
                f"in-stroke alone {f.in_mm:.1f} mm, {agree:.1f} mm apart)")
    if effect == "periodic":
        return (f"{EFFECTS[effect]}; its strongest position-locked window at "
                f"{f.location_mm:.1f} mm of travel (out-stroke alone {f.out_mm:.1f} mm, "
                f"in-stroke alone {f.in_mm:.1f} mm; the lead-periodic projection is "
                f"largest at {f.periodic_mm:.1f} mm)")
    if effect == "takeup" and f.takeup_mm:
        return (f"{EFFECTS[effect]}; extra lag while taking up the reversal: "
                + ", ".join(f"{k}-stroke {v:+.3f} mm ({f.takeup_z.get(k, nan_):+.1f} sd)"
                            for k, v in f.takeup_mm.items()))
    if effect in ("index", "offset") and f.index_at:
        text = f"{EFFECTS[effect]} ({f.index_at})"
        if f.index_at.endswith("position_error_mean"):
            text += shift_text(f.position_shift_mm)
        return text
    return EFFECTS.get(effect, effect)


def location(f: CycleFeatures, effect: str, thresholds: dict[str, float]) -> float | None:
    """Where the named effect is along the stroke (mm), None for an unlocated one: for a
    periodic or localised effect the strongest window of the localised scan (a spot of
    the raceway acts over about a nut length), but only when that scan stands out, i.e.
    is above its threshold: a periodic line spread along the whole stroke has no place of
    its own, and the strongest window of a scan within its healthy range wanders."""
    if effect not in SPECIFIC:
        return None
    thr = thresholds.get("localised", nan_)
    return f.location_mm if f.scores.get("localised", 0.0) > thr else None
