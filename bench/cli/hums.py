"""`bench hums`: thesis chapter 6 (monitoring model, indexes, sweep, RUL) and past it.

    bench hums fit        H1: the monitoring model's position gain by Nelder-Mead
    bench hums sweep      H1-H6: the 11-point degradation sweep, three maneuvers
    bench hums rul        R1-R2: the 120 s run-to-failure run, thesis and fused RUL
    bench hums campaign   >= 20 randomised run-to-failure runs + healthy runs, scored
                          (--usage: 50 actuators with use-driven wear, prognosis)
    bench hums prognose   RUL distribution per actuator from a trends CSV
    bench hums report     self-contained HTML report of one or more logs
    bench hums watch      live: indexes of every command period of a run on the bus
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench import BenchError
from bench.cli import options as opt


def add_subparser(sub: argparse._SubParsersAction) -> None:
    p = opt.add_command(sub, "hums", "health and usage monitoring (thesis chapter 6)", """
        Monitoring model, HUMS indexes, degradation sweep, RUL prediction and reports (thesis
        chapter 6, rows H1-H6, R1-R2).""")
    s = p.add_subparsers(title="hums commands", dest="hums_command", metavar="COMMAND")
    p.set_defaults(func=lambda a: _no_sub(p))
    _add_thesis_commands(s)
    from bench.cli.hums_prognose import add_prognose
    add_prognose(s)
    _add_report(s)
    _add_watch(s)


def _common(q: argparse.ArgumentParser, workers: bool = True) -> None:
    opt.add_set(q, "override a plant parameter (see `bench plant --list-params`)")
    if workers:
        opt.add_workers(q)
        opt.add_scheduler(q)
    opt.add_json(q, "write the results as JSON")


def _add_thesis_commands(s: argparse._SubParsersAction) -> None:
    """fit, sweep, rul and campaign: the thesis' chapter 6 runs."""
    common = _common
    q = opt.add_command(s, "fit", "H1: fit the monitoring model's position gain", """
        Fit the monitoring model's position P gain to a nominal high-fidelity run of the 2 Hz
        sine by Nelder-Mead from 20 (thesis units), as thesis section 6.1 does.""")
    common(q, workers=False)
    q.set_defaults(func=run_fit)

    q = opt.add_command(s, "sweep", "H1-H6: 11-point degradation sweep", """
        Backlash 0-100 um and friction x1-x4 in 11 points, for the open-loop velocity step (H2),
        velocity cosine (H3) and closed-loop sine (H4/H5), without and/or with sensor noise
        (H6).""")
    q.add_argument("--noise", choices=["on", "off", "both"], default="both",
                   help="sensor noise (default: %(default)s)")
    q.add_argument("--points", type=int, default=11, help="degradation points (default 11)")
    opt.add_figures(q, "write PNG figures (figs. 6.2-6.10)")
    opt.add_doc(q, "update the generated sweep section of this markdown file "
                "(e.g. docs/hums.md)")
    common(q)
    q.set_defaults(func=run_sweep)

    q = opt.add_command(s, "rul", "R1-R2: the 120 s run-to-failure run", """
        The H4 sine for 120 s with preload decaying linearly and backlash and friction growing
        exponentially; the thesis' cubic RUL (threshold 0.93, warning 0.80, failure 0.56) with a
        bootstrap band, and the fused predictor.""")
    q.add_argument("--noise", action="store_true", help="sensor noise on (the true failure "
                   "time then comes from a noise-free twin run)")
    q.add_argument("--no-fused", action="store_true",
                   help="only the thesis' algorithm (skips the fusion calibration runs)")
    opt.add_figures(q, "write PNG figures (figs. 6.11-6.15)")
    opt.add_doc(q, "update the generated rul section of this markdown file")
    common(q)
    q.set_defaults(func=run_rul)

    q = opt.add_command(s, "campaign", "randomised run-to-failure campaign, prognostic metrics", """
        N run-to-failure runs with randomised schedule (duration, growth rates, start preload,
        preload decay) and noise seeds, each with a noise-free twin for its true failure time,
        plus healthy runs for false alarms; scored with progpy (prognostic horizon, alpha-lambda
        with alpha = 0.2, relative accuracy).""")
    q.add_argument("--runs", type=int, default=None,
                   help="run-to-failure runs (default 20; with --usage: 50 actuators)")
    q.add_argument("--healthy", type=int, default=None,
                   help="healthy runs (default 10; with --usage: 5 healthy actuators)")
    opt.add_seed(q, 2024, "campaign seed")
    opt.add_figures(q, "write the campaign figure")
    opt.add_doc(q, "update the generated campaign section of this markdown file")
    _add_usage_options(q)
    common(q)
    q.set_defaults(func=run_campaign)


def _add_usage_options(q: argparse.ArgumentParser) -> None:
    """`bench hums campaign --usage` and its options."""
    q.add_argument("--usage", action="store_true",
                   help="the usage campaign instead: actuators with Archard wear "
                   "flown daily under flight profiles of random severity, a daily ground "
                   "test, prognosis from usage and health (docs/hums.md)")
    q.add_argument("--max-days", type=int, default=120,
                   help="with --usage: days after which an actuator is censored (120)")
    q.add_argument("--trends-out", metavar="FILE.csv",
                   help="with --usage: write the judged actuators' daily indexes and "
                   "exposures as a trends CSV (input of `bench hums prognose`)")
    q.add_argument("--calibration-out", metavar="FILE.json",
                   help="with --usage: where to write the prognosis calibration (default: "
                   "the cache `bench hums prognose` reads)")


def _add_report(s: argparse._SubParsersAction) -> None:
    q = opt.add_command(s, "report", "HTML health report of logs", """
        A self-contained HTML report (figures, indexes, verdict, RUL with band) of candump logs
        (decoded through the DBC) or trace files (.npz, .csv, .parquet). Short gaps in a log
        (lost SYNCs, missing frames, NaN rows: up to 5 samples in a row, 2 % in all) are
        bridged and reported; longer ones make the indexes that need the signal 'not available'.
        A log whose verdict index (Ci in position mode, Cp in speed mode) is not available, that
        is shorter than 0.1 s or in which nothing was commanded gets the verdict UNKNOWN. Exit
        status: 0 when every log has a verdict, 3 when one has none (UNKNOWN; the report is
        still written), 2 on bad input. A log the thesis' monitoring model cannot take (no ECU
        mode or speed set-point, e.g. a rig's table at 25 Hz imported with `bench import`) gets
        the model-free indexes, and with --nominal or --baseline the calibrated model's indexes
        or the healthy baseline's features and verdict; what it cannot support is listed as not
        available. Judged against the calibrated model, its verdict needs every signal the
        calibration's healthy logs were scored on (position, and current when they had it) and
        at least 5 position samples: without one the verdict is UNKNOWN (exit 3).""")
    q.add_argument("logs", nargs="+", metavar="LOG", help="bus log (.log, .asc, .blf, .trc, .mf4) or trace file")
    opt.add_out(q, "output directory (default: %(default)s)", default="hums-report")
    q.add_argument("--period", type=float, default=None, metavar="S",
                   help="command period in s (default: from the log)")
    q.add_argument("--no-rul", action="store_true", help="skip the trend/RUL part")
    opt.add_set(q, "nominal plant parameter override")
    q.add_argument("--nominal", metavar="CAL.json",
                   help="another actuator's calibration (bench calibrate --actuator): its "
                        "calibrated model is the monitoring model, or its healthy baseline "
                        "when the model does not reach the noise floor (docs/real-data.md)")
    opt.add_baseline(q)
    q.set_defaults(func=run_report)


def _add_watch(s: argparse._SubParsersAction) -> None:
    q = opt.add_command(s, "watch", "live indexes per command period, listening to the bus", """
        The HUMS as a passive bus client: decodes the ECU's set-points and the actuator's PDOs
        through the DBC, runs the monitoring model alongside and prints (and writes with --out)
        Cp, Ci, peak ratio and lost motion of every command period, with the verdict `bench hums
        report` gives that period (the same rows, lost SYNCs, duplicates and short gaps handled
        alike). Start it, then `bench run` on the same bus (e.g. after `bench up`). Stops on
        Ctrl-C, --duration, or --idle seconds without SYNC once a run was seen.""")
    q.add_argument("--period", type=float, default=0.5, metavar="S",
                   help="command period of the profile (default: %(default)s s, the 2 Hz "
                        "sine)")
    q.add_argument("--duration", type=float, default=None, metavar="S",
                   help="stop after S seconds of listening")
    q.add_argument("--idle", type=float, default=2.0, metavar="S",
                   help="stop S seconds after the last SYNC (default: %(default)s)")
    opt.add_out(q, "one row per period (CSV), appended (a new file, or one a watch wrote)",
                metavar="FILE.csv")
    q.add_argument("--usage", metavar="FILE.json",
                   help="usage of every run so far (bench usage's JSON; a new file or a watch's), "
                        "rewritten every command period; a usage table of each run is "
                        "printed when it ends")
    opt.add_node_id(q)
    opt.add_set(q, "nominal plant parameter override")
    opt.add_bus(q)
    from bench.cli.hums_watch import run_watch
    q.set_defaults(func=run_watch)


def _no_sub(p: argparse.ArgumentParser) -> int:
    p.print_help()
    return 2


DOC_SUFFIXES = (".md", ".markdown")     # --doc's section in a CSV would be appended to data


def _check_args(args: argparse.Namespace, section: str | None = None) -> None:
    """--workers, --seed and the output options given (their directories made; `section`:
    the one --doc gets, in a markdown file, DOC_SUFFIXES), checked before the work."""
    from bench.cli.outputs import check_doc_section, check_output_file, check_outputs
    if getattr(args, "workers", None) is not None and args.workers < 1:
        raise BenchError("--workers must be >= 1")
    check_outputs(args, files=("json", "trends_out", "calibration_out"), dirs=("figures",))
    if section and args.doc:
        check_output_file(args.doc, "--doc", DOC_SUFFIXES, make_parents=True)
        check_doc_section(args.doc, section)


def _print_rows(rows) -> None:
    for r in rows:
        ratio = r.ratio
        rs = f"{ratio:6.3f}" if math.isfinite(ratio) else ""
        print(f"{r.id:4s} {r.quantity[:70]:70s} {str(r.thesis)[:16]:>16s} "
              f"{str(r.project)[:26]:>26s} {rs}")


def _write_json(path: str | None, data) -> None:
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(json.dumps(data, indent=2))
        print(f"wrote {path}")


def _doc_dir(doc: str | None) -> Path | None:
    return Path(doc).parent if doc else None


def _write_figures(args: argparse.Namespace, figures: Callable[[str], list[Path]]
                   ) -> list[Path]:
    """--figures: the run's PNG figures (`figures(folder)`), each path printed."""
    paths = figures(args.figures) if args.figures else []
    for p in paths:
        print(f"wrote {p}")
    return paths


def _write_doc(args: argparse.Namespace, section: str,
               markdown: Callable[[list[Path], Path | None], str], paths: list[Path]) -> None:
    """--doc: its generated `section` rewritten with `markdown(figures, doc folder)`."""
    if args.doc:
        from bench.hums.table import replace_section
        replace_section(args.doc, section, markdown(paths, _doc_dir(args.doc)))
        print(f"updated {args.doc}")


def _write_outputs(args: argparse.Namespace, figures: Callable[[str], list[Path]], data: Any,
                   section: str, markdown: Callable[[list[Path], Path | None], str]) -> None:
    """What a run writes when asked, in this order: its figures, its JSON, its section
    of --doc."""
    paths = _write_figures(args, figures)
    _write_json(args.json, data)
    _write_doc(args, section, markdown, paths)


def _with_links(text: str) -> Callable[[list[Path], Path | None], str]:
    """A --doc section: `text`, then links to the figures."""
    def markdown(paths: list[Path], doc_dir: Path | None) -> str:
        from bench.hums.table import figure_links
        if not paths:
            return text
        return text + "\n" + "\n".join(figure_links(paths, doc_dir)) + "\n"
    return markdown


def run_fit(args: argparse.Namespace) -> int:
    from bench.hums import monitor as M
    params = opt.set_params(args)
    _check_args(args)
    t0 = time.perf_counter()
    fit, _ = M.fitted(params)
    print(f"monitor position gain: {fit.gain_thesis_units:.2f} (rad/s)/V thesis units = "
          f"{fit.gain_rad_s_per_m:.0f} (rad/s)/m (thesis: {M.THESIS_FITTED_GAIN:g})")
    print(f"start {fit.start_thesis_units:g}: RMS position difference "
          f"{fit.rms_start_m * 1e6:.1f} um; fitted: {fit.rms_residual_m * 1e6:.3f} um "
          f"({100 * fit.relative_residual:.3f} % of the RMS position), "
          f"{fit.evaluations} evaluations, converged: {fit.converged}")
    print(f"plant ECU position gain: {fit.plant_gain_rad_s_per_m / 285.7:.2f} thesis units "
          f"({time.perf_counter() - t0:.1f} s)")
    _write_json(args.json, fit.to_json())
    return 0


def run_sweep(args: argparse.Namespace) -> int:
    from bench.core.thesis_rows import check
    from bench.hums import sweep as S
    _check_args(args, "sweep")
    res = S.run(opt.set_params(args), noise=args.noise, points=args.points, workers=args.workers,
                scheduler=args.scheduler)
    rows = S.rows(res)
    _print_rows(rows)
    print(f"{len(res.points)} plant runs in {res.elapsed_s:.1f} s")
    _write_outputs(args, lambda folder: S.figures(res, folder), [r.to_json() for r in rows],
                   "sweep", lambda paths, doc_dir: S.markdown(res, paths, doc_dir))
    missing = check(rows)
    if missing:
        import sys
        print(f"warning: rows {', '.join(missing)} differ from the thesis by > 10 % and no "
              "reason is on record for these parameters; explain them before publishing",
              file=sys.stderr)
    return 0


def run_rul(args: argparse.Namespace) -> int:
    from bench.hums import rul_run as R
    _check_args(args, "rul-noise" if args.noise else "rul")
    from bench.runtime.workers import session
    with session(args.workers, args.scheduler):     # one cluster: the runs, calibration
        res = R.run_rul(opt.set_params(args), noise=args.noise, fused=not args.no_fused,
                        workers=args.workers, scheduler=args.scheduler)
    rows = R.rows(res)
    _print_rows(rows)
    print(f"done in {res.elapsed_s:.1f} s")
    _write_outputs(args, lambda folder: R.figures(res, folder), [r.to_json() for r in rows],
                   "rul-noise" if args.noise else "rul",
                   lambda paths, doc_dir: R.markdown(res, paths, doc_dir))
    return 0


def run_campaign(args: argparse.Namespace) -> int:
    from bench.hums import campaign as R
    _check_campaign_outputs(args)
    if args.usage:
        return _run_usage_campaign(args)
    args.runs = 20 if args.runs is None else args.runs
    args.healthy = 10 if args.healthy is None else args.healthy
    if args.runs < 1 or args.healthy < 0:
        raise BenchError("--runs must be >= 1 and --healthy >= 0")
    from bench.runtime.workers import session
    with session(args.workers, args.scheduler):     # one cluster: calibration, runs
        res = R.run_campaign(args.runs, args.healthy, args.seed, opt.set_params(args),
                             args.workers, scheduler=args.scheduler)
    text = R.campaign_markdown(res)
    print(text)
    _write_outputs(args, lambda folder: R.campaign_figure(res, folder), R.campaign_json(res),
                   "campaign", _with_links(text))
    return 0


def _check_campaign_outputs(args: argparse.Namespace) -> None:
    """The campaign's options, before it starts: those of --usage only without it are
    refused, the calibration's default path (the cache) is checked as --calibration-out."""
    from bench.hums.prognosis_trends import default_calibration_path
    if not args.usage:
        for flag, given in (("--trends-out", args.trends_out),
                            ("--calibration-out", args.calibration_out)):
            if given:
                raise BenchError(f"{flag} is for --usage")
    else:
        args.calibration_out = args.calibration_out or str(default_calibration_path())
    _check_args(args, "usage-campaign" if args.usage else "campaign")


def _run_usage_campaign(args: argparse.Namespace) -> int:
    from bench.hums import prognosis_campaign as PC
    n = 50 if args.runs is None else args.runs
    nh = 5 if args.healthy is None else args.healthy
    if n < 1 or nh < 0 or args.max_days < 2:
        raise BenchError("--runs must be >= 1, --healthy >= 0 and --max-days >= 2")
    from bench.runtime.workers import session
    with session(args.workers, args.scheduler):     # one cluster: simulation, prognosis
        res = PC.run_usage_campaign(n, n_healthy=nh, seed=args.seed, params=opt.set_params(args),
                                    workers=args.workers, max_days=args.max_days)
    text = PC.markdown(res)
    print(text)
    cal_path = Path(args.calibration_out)
    cal_path.parent.mkdir(parents=True, exist_ok=True)
    cal_path.write_text(json.dumps(res.cal.to_json(), indent=1))
    print(f"wrote the prognosis calibration {cal_path}")
    _write_json(args.json, PC.to_json(res))
    if args.trends_out:
        print(f"wrote {PC.write_trends(res, args.trends_out)}")
    paths = _write_figures(args, lambda folder: PC.figure(res, folder))
    _write_doc(args, "usage-campaign", _with_links(text), paths)
    return 0


def _rig_report(args: argparse.Namespace) -> bool:
    """Whether the logs go to the report of another actuator (bench.rig.hums): a
    calibration or baseline is given, or a trace lacks what the monitoring model needs.
    A mix of both kinds of log is refused (one report each)."""
    from bench.bus.logs import load_trace
    from bench.rig.hums import is_rig_log
    if args.nominal or args.baseline or args.against != "auto":
        return True
    kinds = {}
    for p in args.logs:
        if Path(p).suffix.lower() in (".npz", ".csv", ".parquet"):
            kinds[p] = is_rig_log(load_trace(p))
        else:
            kinds[p] = False                 # a bus log decodes to the bench's signals
    if len(set(kinds.values())) > 1:
        rig = [p for p, k in kinds.items() if k]
        raise BenchError(f"{', '.join(rig)}: logs without the ECU's mode and speed "
                         "set-point, mixed with bench logs: report them separately")
    return any(kinds.values())


def _run_rig_report(args: argparse.Namespace) -> int:
    import sys

    from bench.rig.hums import summary_text
    from bench.rig.hums_html import write_rig_report
    if args.set or args.period is not None:
        raise BenchError("--set and --period are for the thesis actuator's report; a log "
                         "of another actuator takes --nominal CAL.json / --baseline BASE.json")
    page, analyses = write_rig_report(args.logs, args.out, args.nominal, args.baseline,
                                      args.against)
    for a in analyses:
        print(summary_text(a))
    print(f"wrote {page}")
    unknown = [a for a in analyses if not a.verdict.judged]
    if unknown:
        print(f"error: no verdict for {', '.join(a.name for a in unknown)} ("
              + "; ".join(a.reasons[-1] for a in unknown) + f"); the report is in {page}",
              file=sys.stderr)
        return 3
    return 0


def run_report(args: argparse.Namespace) -> int:
    from bench.cli.outputs import check_output_dir
    from bench.hums.report import write_report
    if args.period is not None and not (math.isfinite(args.period) and args.period > 0):
        raise BenchError("--period must be > 0 s")
    check_output_dir(args.out, "--out")             # before the logs are analysed
    if _rig_report(args):
        return _run_rig_report(args)
    page, analyses = write_report(args.logs, args.out, opt.set_params(args), rul=not args.no_rul,
                                  period_s=args.period)
    for a in analyses:
        print(f"{a.name}: {a.verdict.name}; " + "; ".join(a.reasons))
        if a.notes:
            print(f"{a.name}: log: " + "; ".join(a.notes))
    print(f"wrote {page}")
    unknown = [a for a in analyses if not a.verdict.judged]
    if unknown:
        import sys
        print(f"error: no verdict for {', '.join(a.name for a in unknown)} ("
              + "; ".join(a.reasons[0] for a in unknown) + f"); the report is in {page}",
              file=sys.stderr)
        return 3
    return 0
