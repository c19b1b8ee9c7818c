"""What else the bench sees on a real rig: known synthetic faults injected into held-out
healthy cycles (`bench rig inject`, docs/real-data.md "What else the bench sees: injected faults").

The baseline and the thresholds come from the healthy calibration runs exactly as
`bench rig study` makes them (`baseline.build` of the calibration cycles,
`population.calibrate_loads`). Each held-out healthy cycle is then scored unmodified
(the false-alarm rate beside the results) and once per fault kind and size with a
synthetic fault written into its logged samples; the features and the verdict are the
ones every cycle gets (`features.cycle_features`, `features.assess`). Reported per kind,
size and load: the share of cycles flagged, the share named as the kind's own effect,
the effects named, and the smallest tested size flagged (and named right) in 90 % of the
cycles.

The fault models (written down, with their rationale, before any result was looked at):

- friction (lack of lubrication, a dry or contaminated nut): a friction torque that
  opposes the motion whatever its direction, so the drive's current is raised in both
  strokes. The Cranfield current is logged as a magnitude (positive in both directions),
  so the model adds a constant offset `delta` (A) to every sample where the set-point
  moves (the out- and in-strokes, ramps included) and leaves the dwells alone (no motion,
  no rolling friction). Size: delta in units of the baseline's spread of the stroke
  current; beside it, delta as a share of the baseline's mean stroke current above the
  standstill (the fraction by which the friction-borne current grew).
- backlash (play between the screw and the nut, a worn or loose nut): the nut follows the
  motor through a play of width b. The play operator (a hysteresis of width b centred on
  the drive side) acts on the logged nut position p: p'_k = min(p_k + b/2, max(p_k - b/2,
  p'_{k-1})), starting as if the motion before the cycle ran the other way (the nut
  trailing by b/2); the position error becomes the set-point less p'. The current is
  unchanged (a play transmits no torque while it is taken up, and the rig's load holds
  the nut against one flank in a stroke). Size: b in units of the baseline's spread of
  the stroke position error, beside it b in mm. Limitation: the logged position's own
  noise passes the operator too (noise smaller than the play is absorbed at standstill).
- loaded_play (a play under a one-sided load): a load of one
  sign over the whole cycle, well above the nut's friction (the Cranfield rig's 20, 40
  and -40 kgf), holds the nut on the loaded flank of the play in both strokes and at
  standstill, so the play is never taken up at a reversal: the nut sits b/2 from where
  the motor puts it, towards the side the load pushes it (`Scales.push`: the sign of the
  load times the actuator description's `load_sign`), in every sample. The logged
  position is shifted by that much; the current is unchanged. Size: b in units of the
  spread of the stroke position error, as for backlash. The kind's own effect: offset
  (a flagged cycle named by a mean position-error index that moved alike in every phase,
  `features.judge`).
- localised (a dent, a spall or debris at one spot of the raceway): while the spot is
  under the nut the balls roll over it and the current is raised; the nut covers about
  `NUT_MM` of travel, so a rectangular bump of height h (A) over a nut length centred on
  a fixed measured position (default: the middle of the baseline's out-stroke travel),
  in both strokes, on the moving samples only. Size: h in units of the spread of the
  stroke current, beside it h in A.
- periodic (something once per screw revolution: a bent or eccentric screw, a defect
  passing under the nut's ball circuit each turn): a sine of the measured position at
  the screw's lead, a sin(2 pi x / lead), added to the current of the moving samples in
  both strokes. Size: a in units of the spread of the stroke current, beside it a in A.

The spread of the stroke current (sigma_I) is the RMS over the out- and in-stroke's
aligned samples of the baseline's per-sample spread of the current the stroke features
read (`features.stroke_signal`: against the standstill); sigma_e is the same for the
position error. Named right: the fault family the verdict names (`naming.attribute`) is
the kind's own: friction -> friction, backlash and loaded_play -> backlash, localised and
periodic -> spall.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.rig import baseline as B
from bench.rig import population as P
from bench.rig.cycles import Cycle, condition_name, read_cycles
from bench.rig.features import assess, cycle_features, location, stroke_signal

KINDS = ("friction", "backlash", "loaded_play", "localised", "periodic")
# the fault family each kind is named right as (`naming.attribute`)
EXPECTED = {"friction": "friction", "backlash": "backlash", "loaded_play": "backlash",
            "localised": "spall", "periodic": "spall"}
SIZES = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0)     # in units of the healthy spread
NUT_MM = 22.0                                # travel a nut covers (about a nut length)
SIZE_MAX = 50.0
"""The largest size --sizes may give, in units of the healthy spread. A play of 50
spreads of the stroke position error is 12-15 mm on the Cranfield rig (sigma_e 0.25-0.30
mm, docs/rig-results.md "Injected faults"), most of the `NUT_MM` a nut covers; a current fault of 50 spreads of the stroke
current is 2.3-2.4 A, about five times the stroke current above the standstill. Larger,
and the injected fault is no longer one the screw and nut could carry (and at 1e308 the
arithmetic overflows to infinity)."""
RATE_GOAL = 0.9                              # "the size found in 90 % of cycles"
UNITS = {"friction": "A", "backlash": "mm", "loaded_play": "mm", "localised": "A",
         "periodic": "A"}


@dataclass
class Scales:
    """One load's units: the healthy spreads the sizes are counted in."""
    load: float
    sigma_i_a: float          # spread of the stroke current (against the standstill), A
    sigma_e_mm: float         # spread of the stroke position error, mm
    stroke_current_a: float   # mean stroke current above the standstill, A
    at_mm: float              # where the localised bump is centred (measured position)
    push: float = 1.0         # the direction the load pushes the nut along x (+1 or -1)

    def physical(self, kind: str, size: float) -> float:
        """A size in sigma -> A (friction, localised, periodic) or mm (the plays)."""
        return size * (self.sigma_e_mm if UNITS[kind] == "mm" else self.sigma_i_a)


def scales(lb: B.LoadBaseline, at_mm: float | None = None, load_sign: float = 1.0
           ) -> Scales:
    """The spreads of one load's baseline over its strokes (RMS of the per-sample
    spreads), its mean stroke current above the standstill, the bump's centre and the
    direction the load pushes the nut (`load_sign`: +1 when a positive logged load pushes
    it to +x)."""
    sig = stroke_signal(lb)
    strokes = [p for p in lb.phases.values() if p.direction != 0]
    if not strokes:
        raise BenchError(f"load {lb.load:g}: the baseline has no stroke")
    si = float(np.sqrt(np.mean(np.concatenate([p.std[sig] for p in strokes]) ** 2)))
    se = float(np.sqrt(np.mean(np.concatenate([p.std["position_error_mm"]
                                               for p in strokes]) ** 2)))
    above = np.concatenate([p.mean[sig] for p in strokes])
    if sig == "current_a":          # an older baseline without the standstill reference
        above = above - np.mean([np.mean(p.mean["current_a"]) for p in lb.phases.values()
                                 if p.direction == 0] or [0.0])
    out = next((p for p in strokes if p.direction > 0), strokes[0])
    mid = 0.5 * (float(np.min(out.position_mm)) + float(np.max(out.position_mm)))
    if at_mm is not None:
        lo = min(float(np.min(p.position_mm)) for p in strokes)
        hi = max(float(np.max(p.position_mm)) for p in strokes)
        if not (math.isfinite(at_mm) and lo <= at_mm <= hi):
            raise BenchError(f"--at-mm {at_mm:g}: outside the measured stroke of load "
                             f"{lb.load:g} ({lo:.1f} to {hi:.1f} mm): give a position in it")
    return Scales(lb.load, si, se, float(np.mean(above)), mid if at_mm is None else at_mm,
                  -load_sign if lb.load < 0 else load_sign)


def moving(cycle: Cycle) -> np.ndarray:
    """True at the samples of the cycle's strokes (the set-point moves)."""
    m = np.zeros(len(cycle), bool)
    for s in cycle.segments():
        if s.direction != 0:
            m[s.start:s.stop] = True
    return m


def friction(cycle: Cycle, delta_a: float) -> Cycle:
    """The current raised by `delta_a` (A) in both strokes (dwells unchanged)."""
    return dataclasses.replace(cycle, current_a=cycle.current_a + delta_a * moving(cycle))


def play(position_mm: np.ndarray, width_mm: float, first_direction: int) -> np.ndarray:
    """The backlash (play) operator of width `width_mm` on a position: the follower
    stays put until the driver has taken up the play, then trails it by half the play.
    It starts as if the motion before ran against `first_direction`."""
    h = 0.5 * width_mm
    y = np.empty_like(position_mm)
    prev = float(position_mm[0]) + first_direction * h if len(position_mm) else 0.0
    for k, x in enumerate(position_mm):
        prev = min(float(x) + h, max(float(x) - h, prev))
        y[k] = prev
    return y


def backlash(cycle: Cycle, width_mm: float) -> Cycle:
    """The logged nut position through a play of `width_mm` (current unchanged)."""
    first = next((s.direction for s in cycle.segments() if s.direction), 1)
    return dataclasses.replace(cycle, position_mm=play(cycle.position_mm, width_mm, first))


def loaded_play(cycle: Cycle, width_mm: float, push: float) -> Cycle:
    """The logged nut position through a play of `width_mm` held on its loaded flank: the
    nut sits half the play from the motor's position towards `push` (+1: +x) in every
    sample (current unchanged)."""
    return dataclasses.replace(cycle, position_mm=cycle.position_mm + push * 0.5 * width_mm)


def localised(cycle: Cycle, height_a: float, at_mm: float, width_mm: float = NUT_MM
              ) -> Cycle:
    """A current bump of `height_a` (A) while the measured position is within half a
    nut length of `at_mm`, in both strokes."""
    bump = (np.abs(cycle.position_mm - at_mm) <= 0.5 * width_mm) & moving(cycle)
    return dataclasses.replace(cycle, current_a=cycle.current_a + height_a * bump)


def periodic(cycle: Cycle, amplitude_a: float, lead_mm: float) -> Cycle:
    """A sine of the measured position at the screw's lead, `amplitude_a` (A), added to
    the current of both strokes."""
    wave = amplitude_a * np.sin(2.0 * np.pi * cycle.position_mm / lead_mm) * moving(cycle)
    return dataclasses.replace(cycle, current_a=cycle.current_a + wave)


def inject(cycle: Cycle, kind: str, size: float, sc: Scales, lead_mm: float) -> Cycle:
    """`cycle` with the fault `kind` of `size` (in units of the load's healthy spread)."""
    x = sc.physical(kind, size)
    if kind == "friction":
        return friction(cycle, x)
    if kind == "backlash":
        return backlash(cycle, x)
    if kind == "loaded_play":
        return loaded_play(cycle, x, sc.push)
    if kind == "localised":
        return localised(cycle, x, sc.at_mm)
    if kind == "periodic":
        return periodic(cycle, x, lead_mm)
    raise BenchError(f"unknown fault kind {kind!r} (known: {', '.join(KINDS)})")


@dataclass
class Cell:
    """One kind, size and load: what the held-out cycles gave."""
    n: int = 0
    flagged: int = 0
    right: int = 0
    effects: dict[str, int] = field(default_factory=dict)
    locations: list[float] = field(default_factory=list)

    def add(self, hit: bool, effect: str, right: bool, where: float | None) -> None:
        self.n += 1
        if hit:
            self.flagged += 1
            self.right += int(right)
            self.effects[effect] = self.effects.get(effect, 0) + 1
            if where is not None and math.isfinite(where):
                self.locations.append(where)

    def to_json(self) -> dict[str, Any]:
        loc = float(np.median(self.locations)) if self.locations else None
        return {"cycles": self.n, "flagged": self.flagged, "named_right": self.right,
                "rate": self.flagged / self.n if self.n else None,
                "right_rate": self.right / self.n if self.n else None,
                "effects": self.effects, "location_mm": loc}


def _judged(lb: B.LoadBaseline, c: Cycle, thr: dict[str, float], lead: float
            ) -> tuple[bool, str, str, float | None]:
    f = cycle_features(lb, c, lead)
    j = assess(f, thr)
    return j.flagged, j.effect, j.fault, (location(f, j.effect, thr) if j.flagged else None)


def _tables(tables: list[str | Path], calibrate_runs: list[int], holdout_runs: list[int],
            lost: list[str]) -> tuple[list[Cycle], list[Cycle], list[str]]:
    """The calibration and the held-out cycles of the tables (each table read once; the
    cycles that cannot be read are listed in `lost`); BenchError naming the run list of
    which the tables have no cycle."""
    cal: list[Cycle] = []
    hold: list[Cycle] = []
    have: set[int] = set()
    for t in tables:
        for c in read_cycles(t, skipped=lost):
            have.add(c.run)
            if c.run in calibrate_runs:
                cal.append(c)
            elif c.run in holdout_runs:
                hold.append(c)
    P.check_runs(cal, hold, calibrate_runs, holdout_runs, have,
                 ", ".join(map(str, tables)))
    return cal, hold, [Path(t).name for t in tables]


def run_inject(tables: list[str | Path], calibrate_runs: list[int],
               holdout_runs: list[int], lead_mm: float, sizes: tuple[float, ...] = SIZES,
               kinds: tuple[str, ...] = KINDS, alpha: float = P.ALPHA,
               at_mm: float | None = None, progress: bool = False, load_sign: float = 1.0
               ) -> dict[str, Any]:
    """The injection study: baseline and thresholds from `calibrate_runs` (as `bench rig
    study`), every held-out cycle scored unmodified and with each kind and size
    (`load_sign`: the actuator description's, for the side a loaded play sits on)."""
    if set(calibrate_runs) & set(holdout_runs):
        raise BenchError("a run cannot be both a calibration and a held-out run")
    t0 = time.perf_counter()
    left_out: list[str] = []          # reported, never dropped silently
    cal, hold, names = _tables(tables, calibrate_runs, holdout_runs, left_out)
    base = B.build(cal, names)
    base.lead_mm = lead_mm
    for lb in base.loads.values():      # a bump outside the stroke: refused before the work
        scales(lb, at_mm)
    cals = P.calibrate_loads(cal, alpha, lead_mm)
    left_out += [f"{c.label}: no healthy calibration run at load {c.load:g}: not scored"
                 for c in hold if c.load not in cals]
    hold = [c for c in hold if c.load in cals]
    why = {id(c): B.incomplete(base.for_load(c.load), c) for c in hold}
    left_out += [f"{c.label}: not judged: {why[id(c)]}" for c in hold if why[id(c)]]
    hold = [c for c in hold if not why[id(c)]]
    if not hold:
        raise BenchError("no held-out cycle at a load the calibration runs have")
    loads = sorted({c.load for c in hold})
    sc = {load: scales(base.for_load(load), at_mm, load_sign) for load in loads}
    cells: dict[tuple[str, float, float], Cell] = {}
    healthy = {load: Cell() for load in loads}
    jobs = [(kind, s) for kind in kinds for s in sizes]
    bar = _bar(len(hold) * (1 + len(jobs)), progress)
    t1 = time.perf_counter()
    for c in hold:
        lb, thr = base.for_load(c.load), cals[c.load].thresholds
        hit, effect, _, where = _judged(lb, c, thr, lead_mm)
        healthy[c.load].add(hit, effect, False, where)
        for kind, s in jobs:
            hit, effect, fault, where = _judged(lb, inject(c, kind, s, sc[c.load], lead_mm),
                                                thr, lead_mm)
            cells.setdefault((kind, s, c.load), Cell()).add(
                hit, effect, fault == EXPECTED[kind], where)
        if bar is not None:
            bar.update(1 + len(jobs))
    if bar is not None:
        bar.close()
    t2 = time.perf_counter()
    res = _result(base, cals, sc, healthy, cells, kinds, sizes, loads, calibrate_runs,
                  holdout_runs, lead_mm, {"total_s": t2 - t0, "scoring_s": t2 - t1,
                                          "cycles_scored": len(hold) * (1 + len(jobs))},
                  condition_name(tables[0]))
    res["left_out"] = left_out
    return res


def _bar(total: int, progress: bool) -> Any:
    if not progress:
        return None
    from tqdm import tqdm
    return tqdm(total=total, desc="inject", unit="cycle")


def _result(base: B.Baseline, cals: dict[float, P.Calibration], sc: dict[float, Scales],
            healthy: dict[float, Cell], cells: dict[tuple[str, float, float], Cell],
            kinds: tuple[str, ...], sizes: tuple[float, ...], loads: list[float],
            cal_runs: list[int], hold_runs: list[int], lead_mm: float,
            cost: dict[str, float], table: str) -> dict[str, Any]:
    """The numbers as JSON-able dicts, with the pooled rows (all loads) and the sizes at
    which 90 % of the cycles are flagged (and named right)."""
    res: dict[str, Any] = {
        "table": table, "baseline": base.describe(), "calibrate_runs": cal_runs,
        "holdout_runs": hold_runs, "lead_mm": lead_mm, "sizes": list(sizes),
        "kinds": list(kinds), "expected": {k: EXPECTED[k] for k in kinds}, "cost": cost,
        "loads": {}, "pooled": {}, "nut_mm": NUT_MM}
    for load in loads:
        res["loads"][f"{load:g}"] = {
            "scales": dataclasses.asdict(sc[load]), "thresholds": cals[load].thresholds,
            "holdout": healthy[load].to_json(),
            "kinds": {k: {f"{s:g}": cells[(k, s, load)].to_json() for s in sizes}
                      for k in kinds}}
    pool_h = Cell()
    for load in loads:
        h = healthy[load]
        pool_h.n += h.n
        pool_h.flagged += h.flagged
        for e, n in h.effects.items():
            pool_h.effects[e] = pool_h.effects.get(e, 0) + n
    res["pooled"]["holdout"] = pool_h.to_json()
    for k in kinds:
        row = {}
        for s in sizes:
            p = Cell()
            for load in loads:
                c = cells[(k, s, load)]
                p.n, p.flagged, p.right = p.n + c.n, p.flagged + c.flagged, p.right + c.right
                p.locations += c.locations
                for e, n in c.effects.items():
                    p.effects[e] = p.effects.get(e, 0) + n
            row[f"{s:g}"] = p.to_json()
        res["pooled"][k] = row
    for where in [res["pooled"]] + list(res["loads"].values()):
        rows = where if where is res["pooled"] else where["kinds"]
        where["at_90"] = {k: {"flagged": size_at(rows[k], sizes, "rate"),
                              "named_right": size_at(rows[k], sizes, "right_rate")}
                          for k in kinds}
    return res


def size_at(row: dict[str, dict[str, Any]], sizes: tuple[float, ...], key: str
            ) -> float | None:
    """The smallest tested size from which every larger tested size reaches 90 % (None
    when the largest does not)."""
    best = None
    for s in sorted(sizes, reverse=True):
        r = row[f"{s:g}"][key]
        if r is None or r < RATE_GOAL:
            break
        best = s
    return best


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.0f} %"


def _effects(eff: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(eff.items(), key=lambda kv: -kv[1])) or "-"


def _size(s: float | None, phys: float | None, unit: str) -> str:
    if s is None:
        return "not reached"
    return f"{s:g} sigma ({phys:.3g} {unit})" if phys is not None else f"{s:g} sigma"


def markdown(res: dict[str, Any], command: str) -> str:
    """The report: units per load, the held-out false alarms, per kind a table of size
    against load (flagged, named right, effects), the sizes at 90 %."""
    lines = [f"Command: `{command}`", "",
             f"Baseline: {res['baseline']}; held-out runs "
             f"{','.join(map(str, res['holdout_runs']))}; lead {res['lead_mm']:g} mm. "
             f"{res['cost']['cycles_scored']} cycles scored in "
             f"{res['cost']['scoring_s']:.1f} s ({res['cost']['total_s']:.1f} s in all).", "",
             "| load | sigma_I (A) | sigma_e (mm) | stroke current above standstill (A) "
             "| bump at (mm) | unmodified held-out cycles flagged (effects) |",
             "|---|---|---|---|---|---|"]
    for key, row in res["loads"].items():
        s, h = row["scales"], row["holdout"]
        lines.append(f"| {key} | {s['sigma_i_a']:.4f} | {s['sigma_e_mm']:.3f} | "
                     f"{s['stroke_current_a']:.3f} | {s['at_mm']:.1f} | {h['flagged']} / "
                     f"{h['cycles']} ({_pct(h['rate'])}); {_effects(h['effects'])} |")
    ph = res["pooled"]["holdout"]
    lines += ["", f"All loads: {ph['flagged']} / {ph['cycles']} unmodified held-out cycles "
              f"flagged ({_pct(ph['rate'])}).", ""]
    lines += [f"Left out: {x}." for x in res.get("left_out", [])]
    keys = list(res["loads"])
    for kind in res["kinds"]:
        unit = UNITS[kind]
        extra = (" (in brackets: of the stroke current above the standstill)"
                 if kind == "friction" else "")
        lines += [f"**{kind}** (named right: {res['expected'][kind]}). Flagged / named "
                  f"right, and the effects named{extra}:", "",
                  "| size (sigma) | " + " | ".join(f"load {k}" for k in keys) + " | all |",
                  "|---|" + "---|" * (len(keys) + 1)]
        for s in res["sizes"]:
            cells = []
            for k in keys:
                c = res["loads"][k]["kinds"][kind][f"{s:g}"]
                phys = s * res["loads"][k]["scales"]["sigma_e_mm" if unit == "mm"
                                                     else "sigma_i_a"]
                share = res["loads"][k]["scales"]["stroke_current_a"]
                frac = (f" ({100 * phys / share:.0f} %)" if kind == "friction" and share > 0
                        else "")
                cells.append(f"{phys:.3g} {unit}{frac}: {_pct(c['rate'])} / "
                             f"{_pct(c['right_rate'])}; {_effects(c['effects'])}")
            p = res["pooled"][kind][f"{s:g}"]
            loc = (f"; located at {p['location_mm']:.1f} mm (median)"
                   if kind == "localised" and p["location_mm"] is not None else "")
            lines.append(f"| {s:g} | " + " | ".join(cells) +
                         f" | {_pct(p['rate'])} / {_pct(p['right_rate'])}{loc} |")
        lines.append("")
    lines += ["Smallest tested size from which every larger one is flagged (named right) "
              "in 90 % of the held-out cycles:", "",
              "| kind | " + " | ".join(f"load {k}" for k in keys) + " | all loads |",
              "|---|" + "---|" * (len(keys) + 1)]
    for kind in res["kinds"]:
        unit = UNITS[kind]
        cells = []
        for k in keys:
            a = res["loads"][k]["at_90"][kind]
            sig = res["loads"][k]["scales"]["sigma_e_mm" if unit == "mm" else "sigma_i_a"]
            cells.append(" / ".join(_size(a[x], None if a[x] is None else a[x] * sig, unit)
                                    for x in ("flagged", "named_right")))
        a = res["pooled"]["at_90"][kind]
        cells.append(" / ".join(_size(a[x], None, unit) for x in ("flagged", "named_right")))
        lines.append(f"| {kind} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def figure(res: dict[str, Any], path: Path) -> Path:
    """Per kind: the share flagged (solid) and named right (dashed) against the size,
    one colour per load, the unmodified held-out false-alarm rate dotted."""
    from matplotlib.figure import Figure
    kinds = res["kinds"]
    fig = Figure(figsize=(3.2 * len(kinds), 3.4))
    axes = fig.subplots(1, len(kinds), squeeze=False)[0]
    sizes = res["sizes"]
    for ax, kind in zip(axes, kinds, strict=True):
        for i, (key, row) in enumerate(res["loads"].items()):
            cells = [row["kinds"][kind][f"{s:g}"] for s in sizes]
            color = f"C{i}"
            ax.plot(sizes, [c["rate"] for c in cells], "o-", color=color,
                    label=f"load {key}: flagged")
            ax.plot(sizes, [c["right_rate"] for c in cells], "s--", color=color, mfc="none",
                    label=f"load {key}: named right")
            ax.axhline(row["holdout"]["rate"], color=color, ls=":", lw=0.8)
        ax.axhline(RATE_GOAL, color="r", lw=0.6)
        ax.set_xscale("log", base=2)
        ax.set_xticks(sizes, [f"{s:g}" for s in sizes])
        ax.set_xlabel("size (healthy sigma)")
        ax.set_title(f"{kind} -> {res['expected'][kind]}")
        ax.set_ylim(-0.03, 1.03)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("share of held-out cycles")
    axes[-1].legend(fontsize=6, loc="lower right")
    fig.suptitle("injected faults: flagged (solid), named right (dashed), "
                 "unmodified held-out flagged (dotted)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    return path


def write(res: dict[str, Any], out: Path, command: str) -> dict[str, Path]:
    """inject.json, inject.md and inject.png in `out`."""
    out.mkdir(parents=True, exist_ok=True)
    paths = {"json": out / "inject.json", "md": out / "inject.md",
             "figure": figure(res, out / "inject.png")}
    paths["json"].write_text(json.dumps(res, indent=1))
    paths["md"].write_text("# Injected faults\n\n" + markdown(res, command) +
                           "\n![injected faults](inject.png)\n")
    return paths


def parse_sizes(text: str | None) -> tuple[float, ...]:
    """--sizes '0.5,1,2' -> (0.5, 1.0, 2.0), sorted and once each (None: `SIZES`);
    BenchError for a size that is not a number in (0, `SIZE_MAX`]."""
    if text is None:
        return SIZES
    try:
        vals = tuple(sorted({float(x) for x in text.split(",") if x.strip()}))
    except ValueError:
        raise BenchError(f"--sizes: expected numbers like 0.5,1,2, got {text!r}") from None
    if not vals or not all(math.isfinite(v) and 0 < v <= SIZE_MAX for v in vals):
        raise BenchError(f"--sizes: every size must be a finite number > 0 and at most "
                         f"{SIZE_MAX:g} (units of the healthy spread; larger is not a "
                         f"physical fault), got {text}")
    return vals


def parse_kinds(text: str | None) -> tuple[str, ...]:
    if text is None:
        return KINDS
    kinds = tuple(k.strip() for k in text.split(",") if k.strip())
    bad = [k for k in kinds if k not in KINDS]
    if bad or not kinds:
        raise BenchError(f"--kinds: unknown {', '.join(bad) or '(none)'} "
                         f"(known: {', '.join(KINDS)})")
    return kinds


def run_cli(args: Any, cal: list[int], hold: list[int], command: str) -> int:
    """`bench rig inject`: run, write the report, print it."""
    import sys
    if args.lead_mm is None:
        raise BenchError("bench rig inject needs the screw's lead (--lead-mm or --actuator)")
    if args.at_mm is not None and not math.isfinite(args.at_mm):
        raise BenchError(f"--at-mm must be a finite position in mm, got {args.at_mm}")
    res = run_inject(args.tables, cal, hold, args.lead_mm, parse_sizes(args.sizes),
                     parse_kinds(args.kinds), args.alpha, args.at_mm,
                     progress=sys.stderr.isatty(), load_sign=getattr(args, "load_sign", 1.0))
    paths = write(res, Path(args.out), command)
    print(markdown(res, command))
    print("written: " + ", ".join(str(p) for p in paths.values()))
    return 0
