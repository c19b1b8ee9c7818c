"""`bench hums report` on a log the thesis' monitoring model cannot take: a
rig's table at its own rate, with set-point, position and current but no ECU mode,
speed set-point or motor angle (e.g. the Cranfield rig at 25 Hz).

Each section declares the signals it needs (`SECTIONS`, read through
`bench.gap.needs.missing`); one the log or the references given cannot support is listed
"not available: <reason>" and the rest runs:

- model-free indexes, always: position error (set-point minus position) mean, peak and
  RMS, and current RMS and peak, per direction of the set-point (extend, retract, dwell);
- with a calibration of `bench calibrate --actuator` (`--nominal CAL.json`): the
  calibrated generic model is the monitoring model: Cp, Ci, mean position error and
  peak-current ratio (eq. 6.4-6.7, `bench.rig.riggap.indexes`) and the RMS residual of
  each signal against the log's noise floor and the calibration's healthy threshold;
- with a healthy baseline (`--baseline BASE.json`, or the one the calibration wrote
  when its model does not reach the noise floor): the phase indexes against the
  baseline's, the rig features (`bench.rig.features`) and their verdict.

The verdict is the baseline's when one is the reference (`bench.rig.fallback.choose`),
else the model's (HEALTHY within its threshold, DEGRADED above; UNKNOWN when the log
lacks a signal the calibration's healthy logs were scored on, or is too short for the
model), else UNKNOWN (no reference); it always states what it was judged against.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import BenchError
from bench.core.verdict import Verdict
from bench.gap import needs as N
from bench.rig import fallback as FB
from bench.rig.cycles import direction_labels
from bench.rig.verdict import baseline_verdict, model_verdict
from bench.signals.trace import Trace

MODEL_FREE = "model-free indexes: position error per direction"
MODEL_FREE_I = "model-free indexes: current per direction"
MODEL_CP = "calibrated model: Cp, mean error (eq. 6.4-6.5)"
MODEL_CI = "calibrated model: Ci, peak ratio (eq. 6.6-6.7)"
BASELINE = "healthy baseline: phase indexes, features, verdict"
THESIS = "thesis monitoring model: Cp, Ci, peak ratio, harmonics (eq. 6.3-6.7)"
LOST = "lost motion (encoder against LVDT)"
TREND = "trend per command period and RUL (fused predictor)"
SECTIONS: dict[str, tuple[str, ...]] = {
    MODEL_FREE: ("setpoint_position_m", "position_m"),
    MODEL_FREE_I: ("setpoint_position_m", "current_a"),
    MODEL_CP: N.NEEDS["rig HUMS index: Cp, mean error (eq. 6.4-6.5)"],
    MODEL_CI: N.NEEDS["rig HUMS index: Ci, peak ratio (eq. 6.6-6.7)"],
    BASELINE: ("setpoint_position_m", "position_m", "current_a"),
    THESIS: N.NEEDS["HUMS: monitoring model"],
    LOST: N.NEEDS["HUMS index: lost motion"],
    TREND: N.NEEDS["HUMS: monitoring model"] + N.NEEDS["HUMS index: lost motion"],
}
"""What each section of the report needs from the log (`bench.gap.needs` notation)."""
DIRECTIONS = {"extend": 1, "retract": -1, "dwell": 0}


@dataclass
class RigAnalysis:
    """One log's report: sections, indexes, reference and verdict."""
    name: str
    trace: Trace
    sections: dict[str, str | None]            # None: available, else the reason
    model_free: dict[str, dict[str, float]]    # direction -> index -> value
    reference: str                             # what the verdict was judged against
    verdict: Verdict = field(default_factory=lambda: Verdict.unknown(()))
    model: dict[str, Any] | None = None
    baseline: dict[str, Any] | None = None
    sim: dict[str, np.ndarray] = field(default_factory=dict)
    base_obj: Any = None
    gap: dict[str, Any] | None = None          # `bench gap`'s diagnosis (riggap), if any

    @property
    def reasons(self) -> list[str]:
        """The verdict's reasons."""
        return list(self.verdict.reasons)

    def to_json(self) -> dict[str, Any]:
        return {"log": self.name, "verdict": self.verdict.name, "reasons": self.reasons,
                "judged_against": self.reference,
                "sections": {k: (v or "available") for k, v in self.sections.items()},
                "model_free": self.model_free, "model": self.model,
                "baseline": self.baseline,
                **({"gap": self.gap} if self.gap is not None else {})}


def is_rig_log(trace: Trace) -> bool:
    """Whether the thesis' monitoring model cannot take `trace` (a signal it needs is
    missing; a bench log at another SYNC period is still the thesis report's)."""
    drive = [n for n in N.NEEDS["HUMS: monitoring model"] if n != N.SYNC_RATE]
    return bool(N.missing(trace, drive))


def model_free(trace: Trace) -> dict[str, dict[str, float]]:
    """Per direction of the set-point (and all): position error (mm) mean, peak |e| and
    RMS; current (A) RMS and peak |i|."""
    have = {s for s in ("setpoint_position_m", "position_m", "current_a")
            if s in trace and np.isfinite(trace[s]).any()}
    if "setpoint_position_m" not in have:
        return {}
    sp = np.nan_to_num(np.asarray(trace["setpoint_position_m"], float))
    lab = direction_labels(sp)
    out: dict[str, dict[str, float]] = {}
    for name, d in {**DIRECTIONS, "all": None}.items():
        m = np.ones(len(sp), bool) if d is None else lab == d
        row: dict[str, float] = {"samples": float(m.sum())}
        if "position_m" in have:
            e = 1e3 * (sp - np.asarray(trace["position_m"], float))[m]
            e = e[np.isfinite(e)]
            if len(e):
                row.update({"position_error_mean_mm": float(np.mean(e)),
                            "position_error_peak_mm": float(np.max(np.abs(e))),
                            "position_error_rms_mm": float(np.sqrt(np.mean(e ** 2)))})
        if "current_a" in have:
            i = np.asarray(trace["current_a"], float)[m]
            i = i[np.isfinite(i)]
            if len(i):
                row.update({"current_rms_a": float(np.sqrt(np.mean(i ** 2))),
                            "current_peak_a": float(np.max(np.abs(i)))})
        out[name] = row
    return out


def _sections(trace: Trace, ref: FB.Reference, rig: bool) -> dict[str, str | None]:
    out: dict[str, str | None] = {}
    for name, needs in SECTIONS.items():
        lack = N.missing(trace, needs)
        out[name] = f"not available: needs {', '.join(lack)}" if lack else None
    if ref.calibration is None:
        why = ("not available: needs a calibration of this actuator (bench calibrate "
               "HEALTHY... --actuator DESC, then --nominal CAL.json)")
        out[MODEL_CP] = out[MODEL_CP] or why
        out[MODEL_CI] = out[MODEL_CI] or why
    else:
        from bench.rig.rigcal import too_short
        short = too_short(trace)
        if short:
            out[MODEL_CP] = out[MODEL_CP] or f"not available: {short}"
            out[MODEL_CI] = out[MODEL_CI] or f"not available: {short}"
    if ref.kind != "baseline":
        out[BASELINE] = out[BASELINE] or (
            "not available: needs a healthy baseline (--baseline BASE.json from bench rig "
            "baseline, or a calibration whose model is above the noise floor, which writes "
            "one)")
    if not rig:
        for k in (THESIS, LOST, TREND):
            out[k] = out[k] or ("not shown: this report is judged against a calibration or "
                                "baseline of another actuator (without --nominal/--baseline "
                                "the thesis report runs)")
    return out


def analyse_rig(trace: Trace, name: str, ref: FB.Reference,
                assessed: dict[str, Any] | None = None) -> RigAnalysis:
    """The report of one log against `ref` (module doc); `assessed`: the log's
    `fallback.assess` result against `ref.baseline` when the caller already has it."""
    rig = is_rig_log(trace)
    sections = _sections(trace, ref, rig)
    if sections[MODEL_FREE] and sections[MODEL_FREE_I]:
        raise BenchError(f"{name}: the HUMS report needs setpoint_position_m with "
                         "position_m or current_a, which this log does not have")
    a = RigAnalysis(name, trace, sections, model_free(trace), ref.line())
    if ref.calibration is not None and sections[MODEL_CP] is None:
        _model(a, ref)
    if ref.kind == "baseline" and ref.baseline is not None and sections[BASELINE] is None:
        _baseline(a, ref, assessed)
    a.verdict = _verdict(a, ref)
    return a


def _model(a: RigAnalysis, ref: FB.Reference) -> None:
    from bench.rig import riggap as RG
    from bench.rig.actuator import from_dict
    cal = ref.calibration
    assert cal is not None
    act = from_dict(cal["actuator_description"], ref.cal_path)
    sim, fl = RG.model_signals(a.trace, cal, act)
    ratios = RG.rms_ratios(a.trace, sim, fl)
    thr = RG.thresholds(cal, ratios)
    a.sim = sim
    a.model = {"calibration": ref.cal_path, "indexes": RG.indexes(a.trace, sim),
               "rms_ratio": ratios, "threshold": thr, "noise_floor": fl,
               "significant": any(ratios[s] > thr[s] for s in ratios),
               "not_judged": RG.not_judged(cal, ratios),
               "reaches_noise_floor": bool(cal.get("reaches_noise_floor")),
               "healthy_ratio": FB.model_ratio(cal)}


def _baseline(a: RigAnalysis, ref: FB.Reference, assessed: dict[str, Any] | None) -> None:
    assert ref.baseline is not None
    try:
        a.baseline = assessed or FB.assess(ref.baseline, a.trace, a.name)
    except BenchError as exc:
        a.sections[BASELINE] = f"not available: {exc}"
        return
    a.base_obj = ref.baseline
    a.reference = ref.line(FB.loads_judged(a.baseline))


def _verdict(a: RigAnalysis, ref: FB.Reference) -> Verdict:
    b = a.baseline
    if b is not None and (v := baseline_verdict(b, a.reference)) is not None:
        return v
    pre = []
    if ref.kind == "baseline":
        why = a.sections[BASELINE] or (b["notes"][-1] if b and b["notes"] else "")
        pre = [f"the healthy baseline gave no verdict ({why})"]
        if a.model is not None:
            a.reference = (f"{ref.line()}; the baseline gave no verdict: judged against "
                           f"the calibrated model {ref.cal_path}")
    m = a.model
    if m is None:
        if ref.kind == "none":
            why = ("no verdict without a reference: a calibration of this actuator "
                   "(--nominal CAL.json) or a healthy baseline (--baseline BASE.json)")
        elif ref.calibration is not None and a.sections[MODEL_CP]:
            why = f"the calibrated model gave no verdict ({a.sections[MODEL_CP]})"
        else:
            why = "no reference this log can be judged against"
        return Verdict.unknown(pre + [why], a.reference)
    return model_verdict(m, a.reference, tuple(pre))


def summary_text(a: RigAnalysis) -> str:
    """The text summary of one log (printed and written as summary.txt)."""
    lines = [f"{a.name}: {a.verdict.name}", f"  judged against: {a.reference}"]
    lines += [f"  {r}" for r in a.reasons]
    for d, row in a.model_free.items():
        vals = ", ".join(f"{k} {v:.4g}" for k, v in row.items() if k != "samples")
        lines.append(f"  model-free, {d} ({int(row['samples'])} samples): {vals}")
    if a.model is not None:
        lines.append("  calibrated model indexes: " + ", ".join(
            f"{k} {v:.{6 if k == 'cp' else 4}g}" for k, v in a.model["indexes"].items()))
    if a.baseline is not None:
        eff = ", ".join(f"{k} {n}" for k, n in a.baseline["effects"].items()) or "none"
        rest = a.baseline["cycles"] - a.baseline["judged_cycles"]
        lines.append(f"  against the baseline: {a.baseline['flagged']} / "
                     f"{a.baseline['judged_cycles']} cycle(s) flagged; effects: {eff}"
                     + (f"; {rest} cycle(s) not judged" if rest else ""))
    for k, v in a.sections.items():
        if v:
            lines.append(f"  {k}: {v}")
    return "\n".join(lines)


def calibration_file(nominal: str) -> dict[str, Any]:
    """A calibration of `bench calibrate --actuator` (BenchError otherwise)."""
    from bench.gap.inputs import BaselineAsNominal, read_nominal
    from bench.rig.riggap import calibration_of, is_rig_doc
    if not Path(nominal).exists():
        raise BenchError(f"no such calibration: {nominal}")
    try:
        data: dict[str, Any] | None = read_nominal(nominal)   # read once
    except BaselineAsNominal:
        raise                          # a baseline given as --nominal: its own message
    except BenchError:
        data = None                    # unreadable or not a JSON object: said below
    if data is None or not is_rig_doc(data):
        raise BenchError(f"{nominal}: not a calibration of `bench calibrate --actuator` "
                         "(the thesis report takes --set NAME=VALUE instead)")
    calibration_of(data, nominal)      # its description, values, method, sample period
    return dict(data)
