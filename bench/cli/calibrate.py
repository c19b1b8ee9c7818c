"""`bench calibrate`: fit the nominal model's uncertain parameters to a healthy log, so
later logs of that actuator are diagnosed against its own baseline (issue 5); or, with
`--actuator`, identify what another actuator's description leaves unknown from one or
more healthy logs and score held-out ones against their noise floor (issue 11)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any


def add_subparser(subparsers: argparse._SubParsersAction) -> None:
    from bench.gap.calibrate import DEFAULT
    from bench.gap.rigcal import METHODS
    p = subparsers.add_parser(
        "calibrate", help="fit the nominal model to a healthy log",
        description="Fit the nominal model's uncertain parameters (inertia, friction level, "
                    "torque constant, lead, sensor gains, current offset) to a healthy log "
                    "by closed-loop least squares with a prior tolerance on each (fast plant "
                    "mode). The output is used by `bench gap --nominal`. With --actuator "
                    "DESC (a JSON/TOML description, or a shipped name: cranfield): identify "
                    "what the description leaves unknown from one or more healthy logs with "
                    "the generic nut-level model, at the logs' own sample instants, and "
                    "report the RMS per signal of each --holdout log against its noise floor.")
    p.add_argument("log", metavar="HEALTHY", nargs="+",
                   help="candump log (.log) or trace of a healthy run (several with --actuator)")
    p.add_argument("--actuator", metavar="DESC",
                   help="another actuator's description (.json/.toml, or: cranfield)")
    p.add_argument("--holdout", metavar="LOG", nargs="+", default=[],
                   help="held-out healthy logs (never the fitted one): with --actuator, scored "
                        "against their noise floor; on the thesis plant, the significance "
                        "level the calibrated model leaves on them is stored "
                        "(heldout_significance), and `bench gap --nominal` judges against it")
    p.add_argument("--controller", choices=METHODS, default="auto",
                   help="with --actuator and an unknown controller: fit-gains (a generic "
                        "cascade fitted in closed loop), measured-current (the logged current "
                        "drives the mechanics), auto (fit-gains when a set-point is logged)")
    p.add_argument("--model", default="plant", metavar="NAME",
                   help="nominal model to calibrate (plant)")
    p.add_argument("--params", metavar="A,B,...", default=",".join(DEFAULT),
                   help=f"parameters to calibrate (default: {','.join(DEFAULT)})")
    p.add_argument("--nominal", metavar="JSON",
                   help="start from these parameters (default: thesis values)")
    p.add_argument("--encoder", choices=("absolute", "relative"), default="absolute",
                   help="encoder angle reference (see bench gap --help)")
    p.add_argument("-o", "--output", metavar="CALIBRATION.json", default="calibration.json",
                   help="where to write the calibration (default calibration.json; '-': stdout)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bench import BenchError
    from bench.cli.outputs import check_output_file
    from bench.gap.inputs import load_log, load_nominal
    check_output_file(args.output, "-o", (".json",), stdout_ok=True)   # before the fit
    if args.actuator:
        return _actuator(args)
    if len(args.log) > 1:
        raise BenchError("several healthy logs need --actuator DESC (the thesis actuator "
                         "is calibrated from one log; give others with --holdout)")
    from bench.gap.calibrate import calibrate, heldout_significance
    from bench.gap.needs import NEEDS, SYNC_RATE, missing
    names = [n.strip() for n in args.params.split(",") if n.strip()]
    if not names:
        raise BenchError("--params lists no parameter")
    log = load_log(args.log[0])
    lack = missing(log, NEEDS["calibrate: thesis plant"])
    # a log of the bench's own at another SYNC period is the thesis plant's to take
    if missing(log, [n for n in NEEDS["calibrate: thesis plant"] if n != SYNC_RATE]):
        raise BenchError(f"{args.log[0]}: the thesis plant's calibration not available: "
                         f"needs {', '.join(lack)}; for another actuator give --actuator "
                         "DESC (docs/real-data.md)")
    same = [h for h in args.holdout if Path(h).resolve() == Path(args.log[0]).resolve()]
    if same:
        raise BenchError(f"--holdout {same[0]} is the calibration log itself: a held-out "
                         "log must be another healthy run")
    held = [load_log(h) for h in args.holdout]
    for h, tr in zip(args.holdout, held, strict=True):
        if missing(tr, [n for n in NEEDS["calibrate: thesis plant"] if n != SYNC_RATE]):
            raise BenchError(f"{h}: held-out log not usable: needs "
                             f"{', '.join(missing(tr, NEEDS['calibrate: thesis plant']))}")
    base = load_nominal(args.nominal)
    cal = calibrate(log, base, names, args.model, args.encoder)
    cal["log"] = str(args.log[0])
    cal["heldout_significance"] = heldout_significance(cal, base, held, list(args.holdout),
                                                       args.encoder, args.model)
    if _write(args.output, cal):
        return 0
    g0, g1 = cal["gap_before"]["heldout_part"]["total"], cal["gap_after"]["heldout_part"]["total"]
    for k, v in cal["params"].items():
        lo, hi = cal["ci95"][k]
        print(f"{k:28s} {v:.6g}  (95 % CI {lo:.6g} .. {hi:.6g}; nominal "
              f"{cal['nominal'][k]:.6g})")
    print(f"held-out gap (RMS, x noise floor): {g0:.3g} -> {g1:.3g}")
    hs = cal["heldout_significance"]
    if hs["known"]:
        print("held-out healthy level (smoothed residual energy / floor; bench gap "
              "--nominal judges against it x margin): " + ", ".join(
                  f"{s} {v:.3g} (x{hs['margin'][s]:.3g})" for s, v in hs["level"].items()))
    else:
        print(f"held-out healthy level: unknown ({hs['note']})")
    for n in cal["notes"]:
        print(f"note: {n}")
    print(f"calibration: {args.output}", file=sys.stderr)
    return 0


def _write(output: str, cal: dict[str, Any]) -> bool:
    """Write the calibration; True when it went to stdout (nothing else to print)."""
    text = json.dumps(cal, indent=1)
    if output == "-":
        print(text)
        return True
    Path(output).write_text(text)
    return False


def _actuator(args: argparse.Namespace) -> int:
    """Another actuator: calibrate, score the held-out logs and, when no model of the
    family reaches the noise floor on them, build the healthy baseline from the
    calibration logs beside the calibration (bench.rig.fallback)."""
    from bench.actuator import load
    from bench.gap.inputs import load_log
    from bench.gap.needs import availability
    from bench.gap.rigcal import calibrate_rig
    from bench.rig.fallback import baseline_for_calibration
    act = load(args.actuator)
    healthy = [load_log(p) for p in args.log]
    held = [load_log(p) for p in args.holdout]
    cal = calibrate_rig(healthy, act, held, args.controller)
    lack = {k: v for k, v in availability(healthy[0]).items() if v}
    cal["not_available"] = lack
    lead_m = act.values.get("lead_m")
    cal["notes"] += baseline_for_calibration(cal, args.log, args.output,
                                             1e3 * lead_m if lead_m else None)
    if _write(args.output, cal):
        return 0
    print(f"{act.name} ({act.motor_kind}): {cal['method_text']}")
    print(f"{len(healthy)} healthy log(s) fitted, {len(held)} held out, "
          f"{cal['seconds']:.1f} s")
    if lack:
        print(f"on these logs ({len(lack)} of the bench's consumers need more):")
        for k, v in lack.items():
            print(f"  {k}: {v}")
    for k in cal["fitted"]:
        lo, hi = cal["ci95"].get(k, [None, None])
        ci = "no effect on the fit" if lo is None or hi is None else f"{lo:.3g} .. {hi:.3g}"
        flag = "  (not identified)" if k in cal["not_identified"] else ""
        print(f"  {k:22s} {cal['values'][k]:.5g}  (95 % CI {ci}){flag}")
    rows = cal["holdout_summary"] or {}
    what = "held-out" if rows else "calibration"
    for sig, r in (rows or _fit_summary(cal)).items():
        print(f"  {what} {sig:12s} RMS {r['rms']:.4g}  noise floor {r['noise_floor']:.4g}  "
              f"ratio {r['ratio_median']:.2f} (median), {r['ratio_max']:.2f} (worst)")
    print("reproduces the healthy logs within "
          f"{cal['floor_factor']:g} x the noise floor: "
          + ("yes" if cal["reaches_noise_floor"] else "no"))
    for n in cal["notes"]:
        print(f"note: {n}")
    print(f"calibration: {args.output}", file=sys.stderr)
    return 0


def _fit_summary(cal: dict[str, Any]) -> dict[str, dict[str, float]]:
    from bench.gap.rigcal import summary
    return summary(cal["fit_scores"])
