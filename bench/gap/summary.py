"""Human-readable summaries of a diagnosis (the `bench gap` console output)."""

from __future__ import annotations

import math
import textwrap
from typing import Any

from bench.gap.localise import BANDS, PATHS, REGIMES

UNIT_SCALE = {"m": (1e6, "um"), "s": (1e3, "ms"), "N/m": (1e-6, "N/um")}


def _scale(unit: str, v: float | None) -> tuple[float, str]:
    if unit == "m" and v is not None and abs(v) >= 1e-3:
        return 1e3, "mm"
    return UNIT_SCALE.get(unit, (1.0, unit))


def fmt_value(v: float | None, unit: str) -> str:
    if v is None or not math.isfinite(v):
        return "n/a"
    k, u = _scale(unit, v)
    return f"{v * k:.4g} {u}".rstrip()


def fmt_params(params: dict[str, Any]) -> str:
    parts = []
    for name, d in params.items():
        lo, hi = (d.get("ci95") or [None, None])
        ci = ""
        if lo is not None and hi is not None:
            k, _ = _scale(d["unit"], d["value"])
            ci = f" [{lo * k:.4g}, {hi * k:.4g}]"
        parts.append(f"{name} = {fmt_value(d['value'], d['unit'])}{ci}")
    return "; ".join(parts)


def _shares(d: dict[str, float], keys: tuple[str, ...] | list[str]) -> str:
    return "  ".join(f"{k} {100 * (d.get(k) or 0.0):.0f}%" for k in keys)


def _model_lines(m: dict[str, Any]) -> list[str]:
    out = [f"model: {m.get('name', '?')} ({m.get('fidelity', '')})"]
    if m.get("load"):
        out.append(f"  load: {m['load']}")
    if m.get("friction_split"):
        out.append(f"  friction split: {m['friction_split']}")
    if m.get("effects_not_representable"):
        out.append("  not tried (this model has no place for them; use --model plant): "
                   + ", ".join(m["effects_not_representable"]))
    return out


def text(js: dict[str, Any], top: int = 8) -> str:
    """Console summary of the diagnosis JSON."""
    loc = js["localisation"]
    sig = loc["significance"]
    out = []
    for key, d in (loc.get("log") or {}).items():
        if d.get("notes"):
            out.append(f"{'log' if key == 'log' else 'held-out log'}: "
                       + "; ".join(d["notes"]))
    out += _model_lines(loc.get("model", {}))
    ns = sig["noise_sigma"]
    out.append("noise (estimated from the log): "
               f"current {ns['current_a']:.3g} A, speed {ns['motor_speed_rad_s']:.3g} rad/s, "
               f"LVDT {ns['position_m'] * 1e6:.3g} um")
    sm = sig["energy_smoothed"]
    thr = sig["threshold"]
    worst = max(sm, key=lambda k: sm[k] / thr[k])
    out.append(f"significant gap: {'yes' if sig['significant'] else 'no'} (smoothed residual "
               f"energy {sm[worst]:.3g}x its floor in {worst}, threshold {thr[worst]:.3g})")
    sigs = loc["signals"]
    out.append("where (share of the excess gap):")
    out.append("  signals  " + "  ".join(f"{s} {100 * sigs[s].get('share', 0):.0f}%"
                                          for s in sigs))
    paths = loc["paths"]
    avail = [p for p in PATHS if paths.get(p, {}).get("available")]
    if avail:
        out.append("  paths    " + "  ".join(
            f"{p} {100 * paths[p].get('share', 0):.0f}% ({paths[p]['energy']:.3g}x floor)"
            for p in avail))
    main = max(sigs, key=lambda s: sigs[s].get("share", 0))
    reg = {r: sigs[main]["by_regime"][r]["energy_share"] for r in REGIMES}
    out.append(f"  regimes  ({main}) " + _shares(reg, REGIMES))
    out.append(f"  bands    ({main}, f0 = {loc.get('fundamental_hz') or float('nan'):.3g} Hz) "
               + _shares(sigs[main]["by_band"], [b[0] for b in BANDS]))
    rk = js["ranking"]
    if rk:
        above = " above the calibration's healthy level" if loc.get("heldout_excess") else ""
        out.append(f"ranking (held-out shrink of the excess gap{above}; BIC, lower is better):")
        for i, c in enumerate(rk[:top], 1):
            sh = c["heldout_shrink_pct"]
            sh_s = f"{sh:6.1f} %" if sh is not None else "   n/a  "
            out.append(f"  {i:2d}. {c['effect']:<28s} shrink {sh_s}  BIC "
                       f"{c['score']['bic']:10.1f}  {fmt_params(c['params'])}")
    sel = loc.get("selection", {})
    v = js["verdict"]
    line = f"verdict: {v}"
    if v == "none":
        line += " (no significant gap: the log is within the noise floor of the model)"
    elif v == "unexplained":
        line += (f" (no candidate shrinks the held-out gap by {sel.get('min_shrink_pct', 50):.0f}"
                 f" %; best: {sel.get('chosen')}, {sel.get('heldout_shrink_pct') or 0:.1f} %)")
    elif sel.get("indistinguishable_from_chosen"):
        line += (" (indistinguishable on this log: "
                 + ", ".join(sel["indistinguishable_from_chosen"]) + ")")
    ja = sig.get("judged_against")
    if ja and ja.get("line"):
        out.append(ja["line"])
    out.append(line)
    if loc.get("limit_cycle"):
        out.append(textwrap.fill(loc["limit_cycle"]["note"], 88, initial_indent="  limit "
                                 "cycle: ", subsequent_indent="    ", break_on_hyphens=False))
    return "\n".join(out)
