"""What a decoded log lost, repeated or had out of order, as short phrases (`integrity`):
from the trace's ``meta`` alone (no bus import), for decoders, importers and the gap
diagnosis."""

from __future__ import annotations

from typing import Any


def _n(count: int, word: str, plural: str | None = None) -> str:
    return f"{count} {word if count == 1 else (plural or word + 's')}"


def integrity(meta: dict[str, Any]) -> list[str]:
    """What a decoded log lost, repeated or had out of order (and the NaN blocks of a
    table from `bench import`), as short phrases, empty for an intact source: for
    `bench decode`, `bench import`, the HUMS report and the gap diagnosis."""
    out = []
    clock = meta.get("clock") or {}
    if clock.get("warning"):
        out.append(clock["warning"])
    gaps = int(meta.get("sync_gaps") or 0)
    if gaps:
        rec = int(meta.get("sync_recovered") or 0)
        out.append(_n(gaps, "lost SYNC") + (f" ({rec} recovered from {'its' if rec == 1 else 'their'}"
                                             " frames)" if rec else ""))
    missing = {k: v for k, v in (meta.get("missing_frames") or {}).items() if v}
    if missing:
        out.append("missing: " + ", ".join(f"{k} in {_n(v, 'period')}"
                                           for k, v in missing.items()))
    dup = int(meta.get("duplicate_frames") or 0)
    if dup:
        out.append(f"{_n(dup, 'duplicate frame')} dropped")
    rep = int(meta.get("replaced_frames") or 0)
    if rep:
        out.append(f"{_n(rep, 'frame')} replaced by a later one of the same SYNC period")
    ooo = int(meta.get("out_of_order") or 0)
    if ooo:
        out.append(f"{_n(ooo, 'frame')} out of time order: decoded in "
                   + ("time-stamp order" if meta.get("sorted_by_time") else "log order"))
    misfit = {k: v for k, v in (meta.get("misfit_frames") or {}).items() if v}
    if misfit:
        out.append(f"{_n(sum(misfit.values()), 'frame')} not fitting the DBC's layout "
                   "(dropped or out of range): " + ", ".join(f"{k} {v}" for k, v in
                                                              misfit.items()))
    for b in meta.get("nan_blocks") or []:        # an imported table (bench import)
        out.append(f"NaN block in {b['column']} ({b['signal']}): table rows "
                   f"{b['first_row']}-{b['last_row']}, t = {b['t0_s']:.3f}-{b['t1_s']:.3f} s, "
                   f"{_n(b['samples'], 'SYNC sample')} left empty")
    return out


def log_integrity(trace: Any, holdout: Any | None) -> dict[str, Any]:
    """What a log (a `bench.signals.trace.Trace`) and its held-out log lost or repeated,
    and what was bridged (the gap diagnosis' `localisation.log`)."""
    out: dict[str, Any] = {}
    for key, tr in (("log", trace), ("holdout", holdout)):
        if tr is None:
            continue
        notes = integrity(tr.meta)
        bridged = {c: int(k) for c, k in (tr.meta.get("bridged") or {}).items()}
        if bridged:
            notes.append("short gaps bridged by interpolation: " + ", ".join(
                f"{c} {k} sample{'s' if k > 1 else ''}" for c, k in bridged.items()))
        out[key] = {"notes": notes, "bridged": bridged}
    return out
