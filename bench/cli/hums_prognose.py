"""`bench hums prognose`: the RUL per actuator from a trends CSV, on the trend's own
prognosis (`bench.hums.trend_prognosis`) or the campaign's calibrated one
(`bench.hums.prognosis_trends`); `bench.hums.trend_run.choose_path` decides."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from bench import BenchError
from bench.cli import options as opt


def add_prognose(s: argparse._SubParsersAction) -> None:
    q = opt.add_command(s, "prognose", "RUL distribution per actuator from health trends", """
        RUL per actuator from a CSV of health-index tests over time (docs/hums.md). Its own
        trend (the default): any index in its unit, times as days or dates; a healthy reference
        from the first tests, a detection of change, and with a failure threshold a RUL band per
        test from a degradation model fitted to the trend, beside a z-score and an exponential
        extrapolation on the same tests. With a calibration of `bench hums campaign --usage`
        whose curves the trends' index names match: the campaign's particle filter instead.""")
    q.add_argument("--trends", required=True, metavar="FILE.csv",
                   help="the trends: a time (or date) column and one column per index, or "
                   "the long form time, actuator, index, value (optional unit); comma, "
                   "semicolon or tab delimited, also compressed; - reads standard input")
    q.add_argument("--date-format", metavar="FMT",
                   help="the time column's dates in this strptime layout, e.g. '%%d/%%m/%%Y' "
                   "(default: ISO 8601 dates, or numbers)")
    q.add_argument("--index", metavar="NAME", help="the index to prognose when the file has "
                   "several")
    q.add_argument("--healthy-tests", metavar="N|DATE",
                   help="the healthy reference: the first N tests, or those up to DATE "
                   "(default: the first 5)")
    q.add_argument("--failure", metavar="LEVEL", help="failure threshold: a level in the "
                   "index's unit (4.6) or a multiple of the healthy level (2x); without it "
                   "a detection, no RUL")
    q.add_argument("--warning", metavar="LEVEL", help="warning level, as --failure (default: "
                   "the warning is the detection of a change from healthy)")
    q.add_argument("--decreasing", action="store_true",
                   help="the index falls as the actuator wears (Ci, say)")
    q.add_argument("--unit", help="the index's unit when the file does not give it (checked "
                   "against the file's when it does)")
    q.add_argument("--time-unit", default="days", metavar="NAME",
                   help="the unit of numeric times, for the output (default days)")
    q.add_argument("--truth", metavar="[ACTUATOR=]DAY|DATE", action="append",
                   help="the true failure time, drawn in the figures (of every actuator, or "
                   "of the one named; repeatable)")
    opt.add_figures(q, "a figure per actuator (the first 100): the trend, its thresholds, "
                    "the RUL band over time")
    q.add_argument("--model", choices=("auto", "trend", "calibration"), default="auto",
                   help="auto (default): the calibration's when the index names match it "
                   "and no option of the trend's own is given; trend; calibration")
    q.add_argument("--calibration", metavar="FILE.json",
                   help="prognosis calibration (default: the one the last `bench hums "
                   "campaign --usage` wrote to the cache)")
    opt.add_seed(q, 0)
    opt.add_workers(q, help="Dask worker processes (default: the trend's own prognosis in "
                    "this process; the calibrated one in this process below 2,000 tests, "
                    "else 2)")
    opt.add_json(q, "write every estimate as JSON")
    q.set_defaults(func=run_prognose)


def run_prognose(args: argparse.Namespace) -> int:

    from bench.cli.outputs import check_outputs
    from bench.hums.trend_io import read_table
    from bench.hums.trend_run import choose_path
    if args.seed < 0:
        raise BenchError(f"--seed must be >= 0, not {args.seed}")
    if args.workers is not None and args.workers < 1:
        raise BenchError("--workers must be >= 1")
    check_outputs(args, files=("json",), dirs=("figures",))
    refuse_inputs_as_outputs(args, outputs=("json",), inputs=("trends", "calibration"),
                             cache_calibration=args.calibration is None)
    if args.calibration and args.model != "trend":
        from bench.hums.prognosis_trends import load_calibration
        load_calibration(args.calibration)      # a given calibration's error comes first
    table = read_table(args.trends, progress=True, date_format=args.date_format)
    for n in table.notes:
        print(f"note: {n}", file=sys.stderr)
    path, cal, why = choose_path(args, table)
    if why:
        print(f"note: {why}", file=sys.stderr)
    if path == "calibration":
        return _prognose_calibrated(args, table, cal)
    return _prognose_own(args, table)


def _prognose_calibrated(args: argparse.Namespace, table, cal) -> int:
    """The campaign's prognosis (bench.hums.prognosis_trends), as before the trend's own."""

    from bench.hums.prognosis_trends import outside_calibration, prognose_trends, to_json
    for n in outside_calibration(table, cal):
        print(f"note: {n}", file=sys.stderr)
    from bench.hums.prognosis_trends import table as text
    results, skipped = prognose_trends(table, cal, args.seed, workers=args.workers,
                                       progress=True)
    if skipped:
        print(f"note: skipped index names the calibration has no curve for: "
              f"{', '.join(skipped)}", file=sys.stderr)
    import json
    if args.json == "-":                # the JSON alone on standard output
        print(text(results), file=sys.stderr)
        json.dump(to_json(results), sys.stdout, indent=2)
        print()
        return 0
    print(text(results))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(to_json(results), indent=2))
        print(f"wrote {args.json}")
    return 0


def refuse_inputs_as_outputs(args: argparse.Namespace, outputs: tuple[str, ...],
                             inputs: tuple[str, ...], cache_calibration: bool = False
                             ) -> None:
    """An output option that names an input file (the same file, by samefile, or the same
    resolved path) is refused before any work: writing it would destroy the input.
    (A command-local check; the shared one in bench.cli.outputs replaces it.)"""
    import os
    paths = [(f"--{k.replace('_', '-')}", getattr(args, k, None)) for k in inputs]
    if cache_calibration:
        from bench.hums.prognosis_trends import default_calibration_path
        paths.append(("the cached calibration", str(default_calibration_path())))
    for out_name in outputs:
        out = getattr(args, out_name, None)
        if not out:
            continue
        for flag, given in paths:
            if not given or "-" in (str(given), str(out)):     # standard input / output
                continue
            same = (os.path.exists(out) and os.path.exists(given)
                    and os.path.samefile(out, given)) or (
                        Path(out).resolve() == Path(given).resolve())
            if same:
                raise BenchError(f"--{out_name.replace('_', '-')} {out} is the input "
                                 f"{flag} {given}: refusing to overwrite it")




def _settings(args: argparse.Namespace) -> Any:
    from bench.hums.trend_prognosis import Settings
    return Settings(healthy=args.healthy_tests, failure=args.failure, warning=args.warning,
                    decreasing=args.decreasing, unit=args.unit, time_unit=args.time_unit,
                    seed=args.seed)


def _truths(given: list[str] | None, trends: list[Any]) -> dict[str, float]:
    """--truth as times of each trend's own (days since its first test for dates):
    actuator -> time."""
    out: dict[str, float] = {}
    names = {tr.actuator for tr in trends}
    for text in given or []:
        who, _, when = text.rpartition("=")
        if who and who not in names:
            raise BenchError(f"--truth {text!r}: no actuator {who!r} in the trends")
        for tr in trends:
            if not who or tr.actuator == who:
                out[tr.actuator] = _truth(when, tr, text)
    return out


def _truth(text: str, trend: Any, given: str) -> float:
    """One --truth value as a time of `trend`'s own."""
    try:
        v = float(text)
        if trend.t0 is None and math.isfinite(v):
            return v
    except ValueError:
        pass
    if trend.t0 is not None:
        from datetime import datetime
        try:
            d = datetime.fromisoformat(text)
            return (d - trend.t0).total_seconds() / 86400.0
        except (ValueError, TypeError):
            pass
    raise BenchError(f"--truth {given!r}: a time as the file gives them "
                     + ("(a date)" if trend.t0 is not None else "(a number)"))


def _prognose_own(args: argparse.Namespace, table: Any) -> int:
    """The trend's own prognosis of every actuator: a line each, the statements of the
    first few, the JSON streamed (`StreamedJson`), figures of the first MAX_FIGURES."""
    from bench.hums import trend_prognosis as TP
    from bench.hums import trend_report as TR
    from bench.hums.trend_run import run, select
    trends = select(table, args.index)
    s = _settings(args)
    for tr in trends:              # every stated level checked before any work
        TP.check(tr, s)
    truth = _truths(args.truth, trends)
    names = [tr.actuator for tr in trends]
    lines: list[str] = []
    said: list[str] = []
    figures: list[Path] = []
    with TR.StreamedJson(args.json) as out:
        def on_result(r: Any) -> None:
            out.add(r)
            lines.append(TR.table([r], names).split("\n", 1)[1])
            if len(lines) <= 3:
                said.extend(TR.statements(r, args.time_unit))
            if args.figures and len(lines) <= TR.MAX_FIGURES:
                figures.append(TR.figure(r, args.figures, truth.get(r.trend.actuator),
                                         args.time_unit))
        run(trends, s, on_result, args.workers)
    out_fh = sys.stderr if args.json == "-" else sys.stdout   # the JSON alone on stdout
    print(TR.table([], names), file=out_fh)
    print("\n".join(lines), file=out_fh)
    print("\n".join(said), file=out_fh)
    if len(trends) > 3:
        print(f"({len(trends) - 3} more actuators: --json for every estimate)", file=out_fh)
    if args.json and args.json != "-":
        print(f"wrote {args.json}")
    if figures:
        more = (f" (the first {TR.MAX_FIGURES} of {len(trends)} actuators)"
                if len(trends) > TR.MAX_FIGURES else "")
        print(f"wrote {len(figures)} figure(s) into {args.figures}{more}", file=out_fh)
    return 0
