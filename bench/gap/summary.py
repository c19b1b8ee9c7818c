"""Human-readable summaries of a diagnosis (the `bench gap` console output)."""

from __future__ import annotations

import math
import textwrap
from typing import Any

from bench.gap.localise import BANDS, PATHS, REGIMES

UNIT_SCALE = {"m": (1e6, "um"), "s": (1e3, "ms"), "N/m": (1e-6, "N/um")}
DIMENSIONLESS = ("-", "")


def _scale(unit: str, v: float | None) -> tuple[float, str]:
    if unit == "m" and v is not None and abs(v) >= 1e-3:
        return 1e3, "mm"
    if unit in DIMENSIONLESS:
        return 1.0, ""
    return UNIT_SCALE.get(unit, (1.0, unit))


def fmt_value(v: float | None, unit: str) -> str:
    """A value in its display unit; a dimensionless one without a unit mark."""
    if v is None or not math.isfinite(v):
        return "n/a"
    k, u = _scale(unit, v)
    return f"{v * k:.{_digits(unit)}g} {u}".rstrip()


def _digits(unit: str) -> int:
    """Significant digits: 5 for a dimensionless value (a gain of 1.0061, a scale), 4
    otherwise."""
    return 5 if unit in DIMENSIONLESS else 4


def fmt_interval(d: dict[str, Any]) -> str:
    """" [lo, hi]" of a parameter's interval in its display unit; a side the fit left
    open (the parameter on a bound, `at_bound`) reads "bound"; "" without one."""
    lo, hi = (d.get("ci95") or [None, None])
    k, _ = _scale(d["unit"], d["value"])
    side = d.get("at_bound")
    if side is None and (lo is None or hi is None):
        return ""
    if lo == hi and side is None and lo is not None:
        return ""                                   # grid-searched: exact on its grid
    n = _digits(d["unit"])
    a = "bound" if side == "lower" or lo is None else f"{lo * k:.{n}g}"
    b = "bound" if side == "upper" or hi is None else f"{hi * k:.{n}g}"
    return f" [{a}, {b}]"


def fmt_params(params: dict[str, Any], names: bool = True) -> str:
    """"name = value [lo, hi]" per parameter ("; "-joined); a parameter at its bound
    says so; `names` False: values only."""
    parts = []
    for name, d in params.items():
        text = f"{fmt_value(d['value'], d['unit'])}{fmt_interval(d)}"
        if d.get("at_bound"):
            text += f" (at its {d['at_bound']} bound)"
        parts.append(f"{name} = {text}" if names else text)
    return "; ".join(parts)


def f0_text(hz: float | None) -> str:
    """'f0 = 2 Hz', or 'no fundamental' when the log has none (a step, a ramp)."""
    return f"f0 = {hz:.3g} Hz" if hz is not None and math.isfinite(hz) else "no fundamental"


def shrink_text(pct: float | None) -> str:
    """A held-out shrink in per cent to one decimal ('n/a' where not measured; a
    shrink that rounds to zero from below reads 0.0, not -0.0)."""
    return "n/a" if pct is None else f"{round(pct, 1) + 0.0:.1f}"


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
    out.append(f"  bands    ({main}, {f0_text(loc.get('fundamental_hz'))}) "
               + _shares(sigs[main]["by_band"], [b[0] for b in BANDS]))
    out += _ranking_lines(js, top)
    line = _verdict_line(js)
    ja = sig.get("judged_against")
    if ja and ja.get("line"):
        out.append(ja["line"])
    out += line
    if loc.get("limit_cycle"):
        out.append(textwrap.fill(loc["limit_cycle"]["note"], 88, initial_indent="  limit "
                                 "cycle: ", subsequent_indent="    ", break_on_hyphens=False))
    return "\n".join(out)


def _ranking_lines(js: dict[str, Any], top: int) -> list[str]:
    """The ranking table, in BIC order (lowest first), the chosen candidate marked (and
    listed after the top ones when it is not among them)."""
    rk = js["ranking"]
    if not rk:
        return []
    loc = js["localisation"]
    above = " above the calibration's healthy level" if loc.get("heldout_excess") else ""
    out = [f"ranking by BIC, lower is better (shrink: of the held-out excess gap{above}):"]
    shown = [c for c in rk[:top]]
    later = [c for c in rk[top:] if c.get("chosen")]
    for c in shown + later:
        if later and c is later[0] and rk.index(c) > top:
            out.append(f"      ... {rk.index(c) - top} more")
        sh = c["heldout_shrink_pct"]
        sh_s = f"{shrink_text(sh):>6s} %" if sh is not None else "   n/a  "
        mark = "  <- chosen" if c.get("chosen") else ""
        flags = "  (suspect)" if c.get("suspect") else ""
        out.append(f"  {c.get('rank', 0):2d}. {c['effect']:<28s} BIC {c['score']['bic']:9.1f}"
                   f"  shrink {sh_s}  {fmt_params(c['params'])}{flags}{mark}")
    chosen = next((c for c in rk if c.get("chosen")), None)
    if chosen is not None and chosen is not rk[0]:
        out.append("  " + _why_not_first(js["localisation"].get("selection", {})))
    return out


def _why_not_first(sel: dict[str, Any]) -> str:
    """Why the chosen candidate is not the lowest BIC (the selection's rules, docs/gap.md,
    "Selection"), in one line."""
    kinds = (("pairs_rejected_as_insignificant", "an added effect insignificant"),
             ("pairs_rejected_below_floor", "an added effect below the floor"),
             ("pairs_rejected_as_suspect", "a suspect value"))
    refused = [f"{len(sel[k])} with {why}" for k, why in kinds if sel.get(k)]
    if not sel.get("best_single_leaves_significant_heldout_gap", True):
        refused.insert(0, "the best single leaves no significant held-out gap")
    tail = (f": {'; '.join(refused)}" if refused else
            ": a pair replaces the best single only where it removes enough of the held-out "
            "gap the single leaves and beats its BIC by a margin")
    return (f"(chosen by the selection's rules, not by the lowest BIC{tail}; "
            "docs/gap.md, \"Selection\")")


def size_note(js: dict[str, Any]) -> str | None:
    """What a verdict's size means where it is not a fitted parameter (friction: the work
    ratio, beside the ranking's scale parameter), or None; the text summary and the HTML
    report both say it."""
    eff = (js.get("finding") or {}).get("effects") or []
    notes = [f"{e['line'].split(' (')[0]}: {e['size']['how']}" for e in eff
             if (e.get("size") or {}).get("how") and e.get("line")]
    return "; ".join(notes) + ". The fitted parameters are in the ranking." if notes else None


def _verdict_line(js: dict[str, Any]) -> list[str]:
    """The verdict in words (its families, sizes and forms) and its trouble."""
    sel = js["localisation"].get("selection", {})
    v = js["verdict"]
    fd = js.get("finding") or {}
    if v == "none":
        return [f"verdict: {v} (no significant gap: the log is within the noise floor of "
                "the model)"]
    if v == "unexplained":
        return [f"verdict: {v} (no candidate shrinks the held-out gap by "
                f"{sel.get('min_shrink_pct', 50):.0f} %; best: {sel.get('chosen')}, "
                f"{sel.get('heldout_shrink_pct') or 0:.1f} %)"]
    out = [f"verdict: {fd.get('line') or v}"]
    notes = [f"candidate {v}"]
    if sel.get("indistinguishable_from_chosen"):
        notes.append("indistinguishable on this log from "
                     + ", ".join(sel["indistinguishable_from_chosen"]))
    if sel.get("same_family_forms"):
        notes.append("other forms of the same family fit as well: "
                     + ", ".join(sel["same_family_forms"]))
    out.append("  (" + "; ".join(notes) + ")")
    if size := size_note(js):
        out.append(f"  {size}")
    if fd.get("edge_note"):
        out.append(f"  {fd['edge_note']} ({', '.join(fd.get('at_bound') or [])})")
    for s in fd.get("suspect") or []:
        out.append(f"  suspect: {s}")
    if sel.get("pairs_rejected_as_suspect"):
        out.append("  pairs not taken, a value suspect: "
                   + ", ".join(sel["pairs_rejected_as_suspect"]))
    if sel.get("pairs_rejected_as_insignificant"):
        out.append("  pairs not taken, the added effect's interval holds no effect: "
                   + ", ".join(sel["pairs_rejected_as_insignificant"]))
    if sel.get("pairs_rejected_below_floor"):
        out.append("  pairs not taken, no signal shows the added effect above the floor: "
                   + ", ".join(sel["pairs_rejected_below_floor"]))
    return out
