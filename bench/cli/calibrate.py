"""`bench calibrate`: fit the nominal model's uncertain parameters to a healthy log, so
later logs of that actuator are diagnosed against its own baseline; or, with
`--actuator`, identify what another actuator's description leaves unknown from one or
more healthy logs and score held-out ones against their noise floor."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from bench.cli import options as opt


def add_subparser(subparsers: argparse._SubParsersAction) -> None:
    from bench.gap.calibrate import DEFAULT
    from bench.gap.library import FRICTION_SPLITS
    thesis, rig = controller_choices()
    p = opt.add_command(subparsers, "calibrate", "fit the nominal model to a healthy log", """
        Fit the nominal model's uncertain parameters (inertia, friction level, torque constant,
        lead, sensor gains, current offset) to a healthy log by closed-loop least squares with a
        prior tolerance on each (fast plant mode). The output is used by `bench gap --nominal`.
        With --actuator DESC (a JSON/TOML description, or a shipped name: cranfield): identify
        what the description leaves unknown from one or more healthy logs with the generic
        nut-level model, at the logs' own sample instants, and report the RMS per signal of each
        --holdout log against its noise floor.""")
    p.add_argument("log", metavar="HEALTHY", nargs="+",
                   help="candump log (.log) or trace of a healthy run (several with --actuator)")
    p.add_argument("--actuator", metavar="DESC",
                   help="another actuator's description (.json/.toml, or: cranfield)")
    p.add_argument("--holdout", metavar="LOG", nargs="+", default=[],
                   help="held-out healthy logs (never the fitted one): with --actuator, scored "
                        "against their noise floor; on the thesis plant, the significance "
                        "level the calibrated model leaves on them is stored "
                        "(heldout_significance), and `bench gap --nominal` judges against it")
    p.add_argument("--controller", choices=tuple(dict.fromkeys(thesis + rig)), metavar="HOW",
                   help="what the calibration does about the controller. The thesis plant: "
                        "bench-ecu (default: the bench's ECU closes the loops), "
                        "fitted-cascade (a generic position/speed cascade identified, to the "
                        "logged current demand when there is one, else in closed loop), "
                        "measured-current (the logged current drives the plant, no "
                        "controller). With --actuator and an unknown controller: auto "
                        "(default: fit-gains when a set-point is logged), fit-gains (a "
                        "generic cascade fitted in closed loop), measured-current (the "
                        "logged current drives the mechanics). The calibration stores the "
                        "controller; bench gap --nominal re-simulates under it")
    p.add_argument("--model", default="plant", metavar="NAME",
                   help="nominal model to calibrate (plant)")
    p.add_argument("--params", metavar="A,B,...",
                   help=f"parameters to calibrate (default: {','.join(DEFAULT)}, the viscous "
                        "friction and, when the log's load cell reads a load, the nut's "
                        "contact stiffness)")
    p.add_argument("--nominal", metavar="JSON",
                   help="start from these parameters (default: thesis values); the "
                        "calibration stores the values that differ from the thesis' "
                        "(base_params), and bench gap --nominal starts from them")
    p.add_argument("--encoder", choices=("absolute", "relative"), default="absolute",
                   help="encoder angle reference (see bench gap --help)")
    p.add_argument("--friction-split", choices=FRICTION_SPLITS,
                   help="the thesis plant: where the model's Coulomb friction acts, at the "
                        "nut or at the screw: unknown (default: a calibrated actuator is "
                        "another one than the thesis', and a datasheet gives a total "
                        "friction) or the model's. A healthy log cannot tell, so the "
                        "calibration only stores it; bench gap --nominal then fits it where "
                        "it shows (see bench gap --help)")
    opt.add_output(p, metavar="CALIBRATION.json", default="calibration.json",
                   help="where to write the calibration (default calibration.json; '-': stdout)")
    p.set_defaults(func=run)


def controller_choices() -> tuple[tuple[str, ...], tuple[str, ...]]:
    """--controller's values on the thesis plant's path (`bench.gap.calibrate.CONTROLLERS`,
    the first the default) and on the --actuator path (`bench.rig.rigcal.METHODS`)."""
    from bench.gap.calibrate import CONTROLLERS
    from bench.rig.rigcal import METHODS
    return tuple(CONTROLLERS), tuple(METHODS)


def controller_of(args: argparse.Namespace) -> str:
    """The --controller value for the path taken (its default when not given); a value
    the other path takes but this one does not is a one-line error."""
    from bench import BenchError
    thesis, rig = controller_choices()
    path, takes = ((rig, "with --actuator (the generic model)") if args.actuator
                   else (thesis, "for the thesis plant (without --actuator)"))
    if args.controller is None:
        return path[0]
    if args.controller not in path:
        raise BenchError(f"--controller {args.controller} is not available {takes}: "
                         f"choose {', '.join(path)}")
    return str(args.controller)


def _thesis_only(args: argparse.Namespace) -> None:
    """With --actuator, the options of the thesis plant's path are refused, not ignored."""
    from bench import BenchError
    if args.friction_split not in (None, "model"):
        raise BenchError("--friction-split is for the thesis plant's model; with "
                         "--actuator the generic model has its own friction law")
    if args.params is not None:
        raise BenchError("--params chooses among the thesis plant's parameters; it does "
                         "not apply with --actuator (the generic model)")


def run(args: argparse.Namespace) -> int:
    from bench import BenchError
    from bench.cli.outputs import check_output_file
    from bench.gap.inputs import load_nominal
    check_output_file(args.output, "-o", (".json",), stdout_ok=True)   # before the fit
    args.controller = controller_of(args)
    distinct_logs(args.log, args.holdout)                   # before the fit
    if args.actuator:
        _thesis_only(args)
        return _actuator(args)
    if len(args.log) > 1:
        raise BenchError("several healthy logs need --actuator DESC (the thesis actuator "
                         "is calibrated from one log; give others with --holdout)")
    from bench.gap.calibrate import calibrate, default_names, heldout_significance
    log, held = _thesis_logs(args)
    names = (list(default_names(log)) if args.params is None
             else [n.strip() for n in args.params.split(",") if n.strip()])
    if not names:
        raise BenchError("--params lists no parameter")
    base = load_nominal(args.nominal)
    cal = calibrate(log, base, names, args.model, args.encoder, controller=args.controller)
    cal["log"] = str(args.log[0])
    if args.nominal:        # the model the calibration started from, for bench gap --nominal
        cal["base_params"] = base_params(base)
    cal["heldout_significance"] = heldout_significance(cal, base, held, list(args.holdout),
                                                       args.encoder, args.model)
    if held:               # where bench gap finds them again (the verdict's model-form term)
        cal["heldout_significance"]["paths"] = [str(Path(h).resolve()) for h in args.holdout]
    # the model's declaration (bench gap): unknown unless told (a calibrated actuator is
    # another one than the thesis', and a healthy log cannot tell where its friction acts)
    cal["friction_split"] = args.friction_split or "unknown"
    if _write(args.output, cal):
        return 0
    g0, g1 = cal["gap_before"]["heldout_part"]["total"], cal["gap_after"]["heldout_part"]["total"]
    z = cal.get("prior_distance_sd", {})
    for k, v in cal["params"].items():
        lo, hi = cal["ci95"].get(k, [None, None])
        ci = f"95 % CI {lo:.6g} .. {hi:.6g}; " if lo is not None and hi is not None else ""
        dist = f", {z[k]:+.1f} prior sd" if k in z else ""
        print(f"{k:32s} {v:.6g}  ({ci}description {cal['nominal'][k]:.6g}{dist})")
    for note in cal.get("notes", []):
        print(f"note: {note}")
    print(f"held-out gap (RMS, x noise floor): {g0:.3g} -> {g1:.3g}")
    print(f"controller: {controller_text(cal['controller'])}")
    print(f"friction split: {cal['friction_split']} (bench gap --nominal uses it)")
    hs = cal["heldout_significance"]
    if hs["known"]:
        print("held-out healthy level (smoothed residual energy / floor; bench gap "
              "--nominal judges against it x margin): " + ", ".join(
                  f"{s} {v:.3g} (x{hs['margin'][s]:.3g})" for s, v in hs["level"].items()))
        print("held-out healthy energy (residual energy / floor on the part a diagnosis "
              "holds out; bench gap --nominal counts its shrink above it): " + ", ".join(
                  f"{s} {v:.3g}" for s, v in hs["energy"].items()))
    else:
        print(f"held-out healthy level: unknown ({hs['note']})")
    for n in cal["notes"]:
        print(f"note: {n}")
    print(f"calibration: {args.output}", file=sys.stderr)
    return 0


def base_params(base: Any) -> dict[str, Any]:
    """The values of the start model (--nominal) that differ from the thesis', flat; `bench
    gap --nominal CAL.json` puts the calibrated params on top of them."""
    from plant_rt.params import PlantParams
    thesis = PlantParams().flat()
    return {k: v for k, v in base.flat().items()
            if not (v == thesis[k] or (v != v and thesis[k] != thesis[k]))}


def _thesis_logs(args: argparse.Namespace) -> tuple[Any, list[Any]]:
    """The calibration log and the held-out ones for the thesis plant; one it cannot take
    is refused with what it needs."""
    from bench import BenchError
    from bench.gap.inputs import load_log
    from bench.gap.needs import NEEDS, SYNC_RATE, missing
    log = load_log(args.log[0])
    lack = missing(log, NEEDS["calibrate: thesis plant"])
    # a log of the bench's own at another SYNC period is the thesis plant's to take
    if missing(log, [n for n in NEEDS["calibrate: thesis plant"] if n != SYNC_RATE]):
        raise BenchError(f"{args.log[0]}: the thesis plant's calibration not available: "
                         f"needs {', '.join(lack)}; for another actuator give --actuator "
                         "DESC (docs/real-data.md)")
    held = [load_log(h) for h in args.holdout]
    for h, tr in zip(args.holdout, held, strict=True):
        if missing(tr, [n for n in NEEDS["calibrate: thesis plant"] if n != SYNC_RATE]):
            raise BenchError(f"{h}: held-out log not usable: needs "
                             f"{', '.join(missing(tr, NEEDS['calibrate: thesis plant']))}")
    return log, held


def distinct_logs(healthy: list[str], holdout: list[str],
                  other: str = "another healthy run") -> None:
    """No held-out log that is one of the fitted ones (the same file, or the same bytes
    under another name): it would score the fit on its own data. A log given twice to
    one option is refused before the command (`outputs.check_io`)."""
    from bench import BenchError
    from bench.cli.outputs import same_bytes, same_file
    for h in holdout:
        for p in healthy:
            if not (Path(h).is_file() and Path(p).is_file()):
                continue                            # load_log says it
            same = ("the same file as" if same_file(h, p) else
                    "the same content as" if same_bytes(h, p) else None)
            if same:
                raise BenchError(f"--holdout {h} is {same} the fitted log {p}: a "
                                 f"held-out log must be {other}")


def controller_text(ctrl: dict[str, Any]) -> str:
    """One line: what a thesis-plant calibration's `controller` entry says."""
    c = ctrl.get("cascade")
    if not c:
        return f"{ctrl['method']} ({ctrl.get('doc', '')})"
    pos = "PI" if c["ki_pos"] else "P"
    return (f"{ctrl['method']}: position {pos} on the {c['source']} (kp {c['kp_pos']:.4g} "
            f"(rad/s)/m, integral zero {c['position_integral_zero_hz']:.3g} Hz), speed PI "
            f"(kp {c['kp_spd']:.4g} A s/rad, zero {c['speed_integral_zero_hz']:.3g} Hz), "
            f"limits {c['speed_limit_rad_s']:.4g} rad/s and {c['current_limit_a']:.4g} A, "
            f"every {c['every_periods']} SYNC period(s)"
            + (f"; fitted to {ctrl['fitted_to']}" if ctrl.get("fitted_to") else ""))


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
    from bench.gap.inputs import load_log
    from bench.gap.needs import availability
    from bench.rig.actuator import load
    from bench.rig.fallback import baseline_for_calibration
    from bench.rig.rigcal import calibrate_rig
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
    from bench.rig.rigcal import summary
    return summary(cal["fit_scores"])
