"""`bench gap`: where the sim-to-real gap lies, which unmodelled effect causes it, how far
it shrinks. See docs/gap.md."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bench.cli import options as opt

if TYPE_CHECKING:
    from bench.signals.trace import Trace


def add_subparser(subparsers: argparse._SubParsersAction) -> None:
    p = opt.add_command(
        subparsers, "gap", "diagnose the gap between a log and the nominal model", """
        Re-simulate a logged run from its set-points, localise the residual (signal, path,
        regime, frequency band), fit a library of candidate effects (least squares, ranked by
        BIC, forward selection of pairs) and measure how far the best one shrinks the gap on
        held-out data. The fits use the plant's fast mode (averaged PWM, massless balls).""")
    p.add_argument("log", nargs="?", metavar="REAL",
                   help="bus log (.log candump, .asc, .blf, .trc, .mf4) or trace "
                        "(.npz/.csv/.parquet) of the run")
    p.add_argument("--holdout", metavar="OTHER",
                   help="another log for held-out validation (default: the last part of REAL)")
    p.add_argument("--holdout-frac", type=float, default=0.5, metavar="F",
                   help="without --holdout: fraction of REAL held out, at its end "
                        "(default 0.5)")
    p.add_argument("--model", default="plant", metavar="NAME",
                   help="nominal model: plant (high-fidelity plant at nominal parameters, "
                        "default) or monitor (HUMS monitoring model)")
    opt.add_effects(p)
    p.add_argument("--nominal", metavar="CALIBRATION.json",
                   help="nominal parameters from `bench calibrate` (default: thesis values): "
                        "its start model with the calibrated values on top, re-simulated "
                        "under the controller it identified (unless the log's metadata names "
                        "one); a calibration of another actuator (--actuator) takes the "
                        "generic model's path")
    opt.add_baseline(p)
    p.add_argument("--encoder", choices=("absolute", "relative"), default="absolute",
                   help="encoder angle reference: absolute (zero at nut zero, the bench's "
                        "plant) or relative (start of the log)")
    from bench.gap.library import FRICTION_SPLITS
    p.add_argument("--friction-split", choices=FRICTION_SPLITS,
                   help="where the model's Coulomb friction acts, at the nut or at the screw: "
                        "the model's (the bench's own plant) or unknown (a model built from a "
                        "datasheet, which gives a total friction): stiffness, preload, "
                        "backlash and friction then also fit the share at the nut. Default: "
                        "what the calibration given with --nominal declares (bench calibrate "
                        "--friction-split), else model")
    p.add_argument("--fundamental", type=float, metavar="HZ",
                   help="command fundamental for the frequency split (default: from the "
                        "log's metadata, else the strongest line of the set-point velocity)")
    opt.add_json(p, "write the diagnosis JSON here ('-': stdout)")
    p.add_argument("--report", metavar="DIR",
                   help="write figures (PNG) and index.html here; against a calibration of "
                        "another actuator or a baseline: the page of bench hums report with the "
                        "gap's diagnosis (index.html, indexes.json, summary.txt)")
    opt.add_workers(p, default=opt.DEFAULT_WORKERS)   # fits in parallel above 1: literal
    opt.add_scheduler(p)
    p.add_argument("--fit-always", action="store_true",
                   help="fit the candidates even when the gap is within the noise floor")
    p.add_argument("--list-effects", action="store_true",
                   help="list the candidate effects with their parameters and exit")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=run)


def list_effects() -> str:
    from bench.gap import effects as E
    lines = []
    for name in E.names():
        e = E.get(name)
        ps = ", ".join(f"{q.name} [{q.lo:g}, {q.hi:g}] {q.unit}" for q in e.params)
        lines.append(f"{name:15s} ({e.where}) {e.doc}\n{'':17s}{ps}")
    return "\n".join(lines)


def _check_numbers(args: argparse.Namespace) -> None:
    from bench import BenchError
    if args.workers < 1:
        raise BenchError("--workers must be >= 1")
    if not (math.isfinite(args.holdout_frac) and 0.0 < args.holdout_frac < 1.0):
        raise BenchError("--holdout-frac must be a fraction between 0 and 1 (exclusive)")
    if args.fundamental is not None and not (math.isfinite(args.fundamental)
                                             and args.fundamental > 0):
        raise BenchError("--fundamental must be a finite frequency > 0 Hz")
    if args.holdout:          # scored on its own data, the held-out shrink would be the fit's
        from bench.cli.calibrate import distinct_logs
        distinct_logs([args.log], [args.holdout], "another log of the actuator")


def _below_nyquist(f0: float, log: Any) -> None:
    """A --fundamental the log can show: below half its sample rate (its harmonics' bands
    are split on the log's own samples)."""
    from bench import BenchError
    dt = log.dt
    if math.isfinite(dt) and dt > 0 and f0 >= 0.5 / dt:
        raise BenchError(f"--fundamental {f0:g} Hz is not below the log's Nyquist frequency "
                         f"{0.5 / dt:g} Hz (a sample every {dt * 1e3:g} ms)")


def run(args: argparse.Namespace) -> int:
    from bench import BenchError
    if args.list_effects:
        print(list_effects())
        return 0
    if not args.log:
        raise BenchError("bench gap needs a log (REAL): a candump .log or a trace file")
    _check_numbers(args)
    from bench.cli.outputs import check_output_dir, check_output_file
    if args.json:                                   # before the diagnosis, not after
        check_output_file(args.json, "--json", (".json",), stdout_ok=True)
    if args.report:
        check_output_dir(args.report, "--report")
    from bench.gap.inputs import read_nominal
    doc = read_nominal(args.nominal) if args.nominal else None   # read once, used by all
    if _is_rig(args, doc):              # before the thesis plant's diagnosis is imported
        return _rig(args, doc)
    from bench.gap import effects as E
    from bench.gap.diagnose import Options, diagnose
    from bench.gap.inputs import load_log
    from bench.gap.summary import text
    names = E.parse_list(args.effects)
    nominal = _nominal(args, doc)
    log = _thesis_log(args)
    hold = load_log(args.holdout) if args.holdout else None
    ctrl_line = _attach_controller(args, doc, log, hold)
    if args.fundamental is not None:
        _below_nyquist(args.fundamental, log)
        log.meta["fundamental_hz"] = args.fundamental
    say = status_printer(args.quiet)
    t0 = time.perf_counter()
    res = diagnose(log, hold, nominal, Options(
        model=args.model, effects=names, holdout_frac=args.holdout_frac,
        workers=args.workers, scheduler=args.scheduler, encoder=args.encoder, fit_always=args.fit_always,
        progress=not args.quiet and sys.stderr.isatty(),
        reference=_calibration_reference(args, doc),
        friction_split=friction_split(args, doc)), log=say)
    js = res.json()
    if ctrl_line:
        js["controller"] = {"line": ctrl_line, **{
            k: v for k, v in log.meta["controller"].items() if k != "structures_tried"}}
    seconds = time.perf_counter() - t0
    say(f"done in {seconds:.1f} s")
    from bench.gap.result_json import gap_document, model_gap_verdict
    doc_js = gap_document(str(args.log), "model",
                          model_gap_verdict(js, _thesis_reference(args, doc)), js,
                          round(seconds, 3))
    if args.json == "-":
        json.dump(doc_js, sys.stdout, indent=1)
        print()
    else:
        print(f"log: {args.log} ({len(log)} samples, {len(log) * log.dt:.3g} s)")
        if ctrl_line:
            print(ctrl_line)
        print(text(js))
        if args.json:
            Path(args.json).write_text(json.dumps(doc_js, indent=1))
            print(f"json: {args.json}")
    if args.report:
        from bench.gap.report import write_report
        idx = write_report(res, js, Path(args.report), doc_js)
        print(f"report: {idx}", file=sys.stderr if args.json == "-" else sys.stdout)
    return 0


def status_printer(quiet: bool) -> Any:
    """The diagnosis' status lines on stderr, through `tqdm.write` so that they land above
    the fits' progress bar instead of breaking it (nothing with --quiet)."""
    if quiet:
        return lambda s: None
    from tqdm import tqdm
    return lambda s: tqdm.write(f"gap: {s}", file=sys.stderr)


def _thesis_reference(args: argparse.Namespace, data: dict[str, Any] | None) -> str:
    """What the thesis plant's diagnosis judged the log against, in words."""
    if not args.nominal:
        return "thesis model (nominal values)"
    name = Path(args.nominal).name
    if data is not None and isinstance(data.get("params"), dict):
        return f"thesis model, calibration {name}"
    return f"thesis model, parameters {name}"


def _calibration_reference(args: argparse.Namespace, data: dict[str, Any] | None
                           ) -> dict[str, Any] | None:
    """The thesis-model calibration given with --nominal (`bench calibrate` output, a
    JSON with "params"; `data`, its object): its name and held-out healthy level for the
    significance test (`bench.gap.calibrate.reference_of`); None for thesis values or a
    parameter file."""
    if data is None or not isinstance(data.get("params"), dict):
        return None
    from bench.gap.calibrate import reference_of
    ref = reference_of(data, Path(args.nominal).name, args.model, args.encoder)
    found = [x for x in ref["paths"] if Path(x).is_file()]
    if found:              # the first held-out healthy log: the verdict's model-form term
        from bench.gap.inputs import load_log
        from bench.gap.problem import under_controller
        healthy = load_log(found[0])
        under_controller(healthy, data.get("controller"))
        ref["healthy_logs"] = [healthy]
        ref["healthy_names"] = [found[0]]
    elif ref["paths"]:
        print(f"note: the calibration's held-out healthy log {ref['paths'][0]} is not found: "
              "the verdict's intervals leave out the model family's misfit", file=sys.stderr)
    return ref


def friction_split(args: argparse.Namespace, data: dict[str, Any] | None) -> str:
    """--friction-split when given; else what the calibration given with --nominal
    (`data`, its object) declares (`bench calibrate --friction-split`, its
    "friction_split"); else "model"."""
    if args.friction_split:
        return str(args.friction_split)
    if data is None:
        return "model"
    from bench import BenchError
    from bench.gap.library import FRICTION_SPLITS
    declared = data.get("friction_split", "model")
    if declared not in FRICTION_SPLITS:
        raise BenchError(f"{args.nominal}: friction_split {declared!r} is not one of "
                         f"{', '.join(FRICTION_SPLITS)}")
    return str(declared)


def _nominal(args: argparse.Namespace, data: dict[str, Any] | None) -> Any:
    """The model of --nominal (`data`, its object): for a thesis-plant calibration its
    start model (`base_params`, the values of `bench calibrate --nominal` that differ
    from the thesis') with the calibrated params on top; else its params on the thesis
    values, or the parameter file; the thesis values without --nominal."""
    from bench.gap.inputs import nominal_params
    from plant_rt.params import PlantParams
    if data is None:
        return PlantParams()
    if not (isinstance(data.get("base_params"), dict)
            and isinstance(data.get("params"), dict)):
        return nominal_params(data, args.nominal)
    from bench import BenchError
    from plant_rt.params import ParameterError
    try:
        return PlantParams().with_dict({**data["base_params"], **data["params"]})
    except ParameterError as exc:
        raise BenchError(f"{args.nominal}: {exc}") from None


def _attach_controller(args: argparse.Namespace, data: dict[str, Any] | None, log: Trace,
                       hold: Trace | None) -> str | None:
    """When the calibration given with --nominal identified the controller (`bench
    calibrate --controller fitted-cascade|measured-current`) and the log's metadata names
    none, attach the calibration's to the log (and the --holdout log), so the diagnosis
    re-simulates under it (`bench.gap.problem.drive_of`); the line saying so, None when
    the bench's ECU closes the loops. `data`: the --nominal file's object."""
    if data is None:
        return None
    ctrl = data.get("controller")
    mine = ctrl.get("method", "bench-ecu") if isinstance(ctrl, dict) else "bench-ecu"
    own = log.meta.get("controller")
    if isinstance(own, dict):
        theirs = own.get("method", "bench-ecu")
        return None if theirs == mine == "bench-ecu" else (
            f"re-simulated under the controller its metadata names ({theirs}), not the "
            f"calibration's ({mine})")
    if not isinstance(ctrl, dict) or mine == "bench-ecu":
        return None
    from bench.cli.calibrate import controller_text
    from bench.gap.problem import under_controller
    for tr in (log, hold):
        if tr is not None:
            under_controller(tr, ctrl)
    name = Path(args.nominal).name
    how = (f"under the controller identified by calibration {name}" if ctrl.get("cascade")
           else f"as calibration {name} handles the controller")
    return f"re-simulated {how}: {controller_text(ctrl)}"


def _is_rig(args: argparse.Namespace, data: dict[str, Any] | None) -> bool:
    """Whether --nominal (`data`, its object) is another actuator's generic calibration
    (bench.rig.riggap) or a healthy baseline is given."""
    from bench import BenchError
    from bench.rig.riggap import is_rig_doc
    rig = data is not None and is_rig_doc(data)
    if not rig and (args.baseline or args.against != "auto"):
        if args.nominal:
            raise BenchError(f"--baseline/--against need a calibration of another actuator "
                             f"(bench calibrate --actuator); {args.nominal} is not one")
        if not args.baseline:
            raise BenchError(f"--against {args.against} needs --nominal CAL.json of another "
                             "actuator (bench calibrate --actuator) or --baseline BASE.json")
    return rig or bool(args.baseline)


def _thesis_log(args: argparse.Namespace) -> Trace:
    """The log for the thesis plant's diagnosis; one it cannot take is refused with what
    it needs and where to go instead."""
    from bench import BenchError
    from bench.gap.inputs import load_log
    from bench.gap.needs import NEEDS, SYNC_RATE, missing
    log = load_log(args.log)
    lack = missing(log, NEEDS["gap: closed-loop re-simulation"])
    # a log of the bench's own at another SYNC period is the thesis plant's to take
    if missing(log, [n for n in NEEDS["gap: closed-loop re-simulation"] if n != SYNC_RATE]):
        raise BenchError(f"{args.log}: the thesis plant's gap diagnosis not available: needs "
                         f"{', '.join(lack)}; for another actuator: bench calibrate HEALTHY... "
                         "--actuator DESC, then bench gap LOG --nominal CALIBRATION.json "
                         "(docs/real-data.md)")
    return log


def _rig(args: argparse.Namespace, data: dict[str, Any] | None) -> int:
    """The log against another actuator's generic calibration (bench.rig.riggap), or
    against the healthy baseline when the calibration's model does not reach the noise
    floor or a baseline is given (bench.rig.fallback)."""
    from bench import BenchError
    from bench.gap.inputs import load_log
    from bench.rig import fallback as FB
    from bench.rig.riggap import CANDIDATES, calibration_of, diagnose_rig, text
    if args.friction_split not in (None, "model"):
        raise BenchError("--friction-split is for the thesis plant's model; a rig's "
                         "calibration has its own friction law")
    cal, act = calibration_of(data, args.nominal) if data is not None else (None, None)
    ref = FB.choose(cal, args.nominal, args.baseline, args.against)
    if ref.kind == "baseline":
        return _rig_baseline(args, ref)
    assert cal is not None and act is not None
    names = tuple(CANDIDATES)
    if args.effects:
        names = tuple(n.strip() for n in args.effects.split(",") if n.strip())
        bad = [n for n in names if n not in CANDIDATES]
        if bad:
            raise BenchError(f"unknown effect(s) {', '.join(bad)} for a generic calibration "
                             f"(effects: {', '.join(CANDIDATES)})")
    from bench.gap.result_json import gap_document
    from bench.rig.verdict import model_verdict
    log = load_log(args.log)
    js = diagnose_rig(log, cal, act, names)
    doc = gap_document(str(args.log), "model",
                       model_verdict(js, ref.line(), effect=str(js["verdict"])), js)
    return _rig_out(args, doc, ref.line() + "\n" + text(js),
                    lambda: _rig_report(args, log, ref, gap=js))


def _rig_baseline(args: argparse.Namespace, ref: object) -> int:
    """The log's cycles against the healthy baseline (bench.rig.fallback.assess)."""
    from bench import BenchError
    from bench.rig import fallback as FB
    assert isinstance(ref, FB.Reference) and ref.baseline is not None
    t0 = time.perf_counter()
    from bench.bus.logs import load_trace
    log = load_trace(args.log)
    try:
        res = FB.assess(ref.baseline, log, Path(args.log).name)
    except BenchError as exc:
        raise BenchError(f"{args.log}: the gap against the healthy baseline not available: "
                         f"{exc}") from None
    from bench.core.verdict import Verdict
    from bench.gap.result_json import gap_document
    from bench.rig.verdict import baseline_verdict
    line = ref.line(FB.loads_judged(res))
    v = baseline_verdict(res, line) or Verdict.unknown(
        [f"the healthy baseline gave no verdict ({res['notes'][-1] if res['notes'] else ''})"],
        line)
    doc = gap_document(str(args.log), "baseline", v, res, round(time.perf_counter() - t0, 3))
    return _rig_out(args, doc, line + "\n" + FB.text(res),
                    lambda: _rig_report(args, log, ref, assessed=res))


def _rig_report(args: argparse.Namespace, log: Trace, ref: Any,
                gap: dict[str, Any] | None = None, assessed: dict[str, Any] | None = None
                ) -> Path:
    """--report DIR on the rig path: the page of `bench hums report` with the gap's
    diagnosis (bench.rig.hums_html.write_gap_report)."""
    from bench.rig.hums_html import write_gap_report
    return write_gap_report(log, Path(args.log).name, ref, args.report, gap, assessed)


def _rig_out(args: argparse.Namespace, js: dict, text: str, report: Any) -> int:
    page = report() if args.report else None
    if args.json == "-":
        json.dump(js, sys.stdout, indent=1, default=str)
        print()
        if page is not None:
            print(f"report: {page}", file=sys.stderr)
        return 0
    print(f"log: {args.log}")
    print(text)
    if args.json:
        Path(args.json).write_text(json.dumps(js, indent=1, default=str))
        print(f"json: {args.json}")
    if page is not None:
        print(f"report: {page}")
    return 0
