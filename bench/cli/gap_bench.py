"""`bench gap-bench`: blind check of the gap diagnosis on generated logs."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bench.cli import options as opt


def add_subparser(subparsers: argparse._SubParsersAction) -> None:
    p = opt.add_command(
        subparsers, "gap-bench", "blind check of the gap diagnosis on generated logs", """
        Generate logs with the plant in-process (bench.sim.harness, full fidelity: switching PWM,
        dynamic balls; sensor noise on) with zero, one or two effects at random magnitudes the
        diagnosis is not told, plus sensor-side effects applied to the logged columns and
        out-of-library effects; run the diagnosis (fast mode) on the measured columns only;
        score top-1 attribution, pair recovery, parameter error, held-out shrink and false
        attribution on nominal logs. Uses both cores.""")
    p.add_argument("--cases", type=int, default=40, metavar="N", help="number of logs (40)")
    opt.add_seed(p, 2025, "case seed", metavar="S")
    opt.add_workers(p, default=opt.DEFAULT_WORKERS)   # recorded in the results: literal
    opt.add_scheduler(p)
    p.add_argument("--log-s", type=float, default=10.0, metavar="S",
                   help="length of each generated log (10 s)")
    p.add_argument("--fidelity", choices=("full", "fast"), default="full",
                   help="plant mode of the generated logs (full; bench generator only)")
    p.add_argument("--generator", choices=("bench", "independent", "final-check"),
                   default="bench",
                   help="who writes the logs: the bench's own plant (bench, default), the "
                        "independent actuator of indie_plant (other physics and parameters; "
                        "the bench calibrates its model on healthy logs first), or the final "
                        "check: three randomised builds of it with physics no development run "
                        "switched on, fixed cases (docs/gap-results.md; --cases and --seed "
                        "do not apply)")
    p.add_argument("--build-seed", dest="build_seed", type=int, metavar="S",
                   help="final check: the first of its three build seeds (S, S+1, S+2; noise "
                        "seeds follow, bench.gap.finalcheck.noise_base); 9101 the first "
                        "check, 9301 the second (default 9101)")
    p.add_argument("--controller", choices=("ecu", "own"), default="ecu",
                   help="independent generator: the bench's ECU closes the loops, as over "
                        "the bus (ecu, default), or the actuator's own PI+PI cascade (own)")
    p.add_argument("--identify", choices=("fitted-cascade", "measured-current"),
                   help="independent generator, --controller own: how the calibration deals "
                        "with the controller it does not know: fit a generic cascade "
                        "(fitted-cascade, default) or drive the model by the measured current")
    p.add_argument("--indie-set", dest="indie_set", action="append", default=[],
                   metavar="NAME=VALUE",
                   help="independent generator: change the actuator as built (all logs, "
                        "calibration included), e.g. speed_window=1; names: python -m "
                        "indie_plant --list-params")
    opt.add_effects(p, "; the generator's effects are unchanged")
    p.add_argument("--only", metavar="EFFECT",
                   help="independent generator: every case is this one effect at a random "
                        "magnitude (a benchmark aimed at one effect; no nominal cases)")
    opt.add_json(p, "write every case and the summary here")
    p.add_argument("--markdown", metavar="PATH", help="write the results table (markdown)")
    p.set_defaults(func=run)


def markdown(out: dict) -> str:
    if out.get("generator") == "independent":
        return independent_markdown(out)
    if out.get("generator") == "final-check":
        return final_markdown(out)
    return _table(out)


def final_markdown(out: dict) -> str:
    """The final check: every case of every actuator, then the goal table."""
    lines = [f"Final check: {len(out['actuators'])} randomised builds (seeds "
             f"{', '.join(map(str, out['build_seeds']))}), physics "
             + ", ".join(f"{k} = {v:g}" for k, v in out["physics"].items())
             + f", {out['cases']} cases, wall {out['wall_s']:.0f} s.", "",
             "| actuator | withheld | above floor | verdict | right family | size error |",
             "|---|---|---|---|---|---|"]
    for r in out["results"]:
        ok = r.get("top1", r.get("pair_verdict", r["verdict"] == "none"))
        err = ", ".join(f"{100 * e:.0f} %" for e in r["param_rel_err"].values()) or "-"
        lines.append(f"| {r['actuator']} | {r['case_name']} | "
                     f"{'yes' if r['above_floor'] else 'no'} | "
                     f"{(r.get('finding') or r['verdict']).replace('|', '/')} | "
                     f"{'yes' if ok else 'NO'} | {err} |")
    lines.append("")
    return "\n".join(lines) + "\n" + _table(out)


def independent_markdown(out: dict) -> str:
    """The independent generator's results: calibration, held-out healthy residual per
    signal (goal: within 2x of the noise floor), then the blind table."""
    cal = out["calibration"]
    held = out["heldout_healthy"]
    lines = [
        f"Generator: independent (indie_plant), controller {out['controller']}"
        + (", actuator changed: " + ", ".join(f"{k} = {v:g}" for k, v in
                                              out["actuator_changes"].items())
           if out.get("actuator_changes") else "")
        + (f", every case a single {out['only']} (--only)" if out.get("only") else "")
        + ". Calibration "
        f"(bench.gap.calibrate, default parameters) on one healthy log, noise seed "
        f"{cal['seed']}, {cal['wall_s']:.0f} s: "
        + ", ".join(f"{k} = {v:.4g}" for k, v in cal["params"].items()) + ".",
        "",
        _controller_line(cal.get("controller")),
        "",
        "Where the model's Coulomb friction acts: "
        + ("unknown (a datasheet gives a total friction): stiffness, preload, backlash and "
           "friction also fit the share at the nut." if out.get("friction_split") == "unknown"
           else "the model's split."),
        "",
        f"Held-out healthy log (noise seed {held['seed']}), calibrated model re-simulated "
        "as the calibration says:",
        "",
        "| signal | RMS residual | noise floor | ratio | goal <= 2 |",
        "|---|---|---|---|---|",
    ]
    for sig, d in held["signals"].items():
        lines.append(f"| {sig} | {d['rms']:.4g} | {d['noise_floor']:.4g} | {d['ratio']:.2f} "
                     f"| {'met' if d['ratio'] <= 2.0 else 'NOT met'} |")
    lines.append("")
    return "\n".join(lines) + "\n" + _table(out, top1_goal=0.8, nominal_goal=0.9)


def _controller_line(ctrl: dict | None) -> str:
    """What the calibration did about the controller (bench.gap.calibrate)."""
    if not ctrl:
        return "Controller: the bench's ECU."
    line = f"Controller: {ctrl['method']} ({ctrl['doc']})"
    c = ctrl.get("cascade")
    if c:
        line += (f"; identified: position {'PI' if c['ki_pos'] else 'P'} on the "
                 f"{c['source']} (kp {c['kp_pos']:.4g} (rad/s)/m, integral zero "
                 f"{c['position_integral_zero_hz']:.3g} Hz), speed PI (kp {c['kp_spd']:.4g} "
                 f"A s/rad, zero {c['speed_integral_zero_hz']:.3g} Hz), limits "
                 f"{c['speed_limit_rad_s']:.4g} rad/s and {c['current_limit_a']:.4g} A, every "
                 f"{c['every_periods']} SYNC periods, fitted to {ctrl.get('fitted_to', '?')}")
    return line + "."


def _table(out: dict, top1_goal: float = 0.9, nominal_goal: float = 0.95) -> str:
    s = out["summary"]

    def rate(d: dict) -> str:
        if not d or d.get("rate") is None:
            return "n/a (0 cases)"
        return f"{100 * d['rate']:.0f} % ({d['hits']}/{d['n']})"

    def goal(d: dict, g: float) -> str:
        if not d or d.get("rate") is None:
            return "not measured"
        return "met" if d["rate"] >= g else "NOT met"

    shr = s["median_heldout_shrink_pct"]
    err = s["param_rel_err_median"]
    err_s = "n/a" if err is None else f"{100 * err:.1f} %"
    lines = [
        f"Seed {out['seed']}, {out['cases']} cases, {out['log_s']:g} s logs, generator "
        f"fidelity {out['fidelity']}, {out['workers']} workers, wall {out['wall_s']:.0f} s "
        f"(mean {s['mean_diagnosis_s']:.1f} s per diagnosis on one core).",
        "",
        "| metric | result | goal | |",
        "|---|---|---|---|",
        f"| top-1, single effects above the noise floor | {rate(s['single_top1_above_floor'])} "
        f"| >= {100 * top1_goal:.0f} % | {goal(s['single_top1_above_floor'], top1_goal)} |",
        f"| top-1 or reported as indistinguishable, same cases | "
        f"{rate(s['single_top1_or_tie_above_floor'])} | (info) | |",
        f"| true pair in the top two, all two-effect cases | {rate(s['pair_in_top2'])} "
        f"| >= 70 % | {goal(s['pair_in_top2'], 0.7)} |",
        f"| true pair in the top two, both effects above the floor | "
        f"{rate(s['pair_in_top2_above_floor'])} | (info) | |",
        f"| median held-out shrink, effect cases above the floor | "
        f"{'n/a' if shr is None else format(shr, '.1f') + ' %'} (n = {s['heldout_shrink_n']}) "
        f"| >= 70 % | "
        f"{'not measured' if shr is None else ('met' if shr >= 70 else 'NOT met')} |",
        f"| nominal logs reported 'no significant gap' | {rate(s['nominal_no_gap'])} "
        f"| >= {100 * nominal_goal:.0f} % | {goal(s['nominal_no_gap'], nominal_goal)} |",
        f"| median parameter error, correctly attributed (rel. to the deviation) | "
        f"{err_s} (n = {s['param_rel_err_n']}) | | |",
        f"| top-1 by family, the goal's effects (friction, backlash, preload, delay, gain, "
        f"current offset, lead) above the floor | {rate(s.get('goal_single_top1_above_floor'))}"
        f" | >= {100 * top1_goal:.0f} % | "
        f"{goal(s.get('goal_single_top1_above_floor'), top1_goal)} |",
        f"| top-1 by the very candidate, single effects above the floor | "
        f"{rate(s.get('single_top1_exact_above_floor'))} | (info) | |",
        f"| size of a correct top-1 within 25 % of the truth | "
        f"{rate(s.get('size_within_25pct_of_correct_top1'))} | 100 % | "
        f"{goal(s.get('size_within_25pct_of_correct_top1'), 1.0)} |",
        f"| the truth inside the interval, correct top-1 | "
        f"{rate(s.get('truth_in_interval_correct_top1'))} | (info) | |",
        f"| friction growth named friction | {rate(s.get('friction_named_friction'))} | "
        f"100 % | {goal(s.get('friction_named_friction'), 1.0)} |",
        f"| friction growth: the truth inside its interval | "
        f"{rate(s.get('friction_truth_in_interval'))} | 100 % | "
        f"{goal(s.get('friction_truth_in_interval'), 1.0)} |",
        f"| a delay named a delay | {rate(s.get('delay_named_delay'))} | 100 % | "
        f"{goal(s.get('delay_named_delay'), 1.0)} |",
        f"| a delay named a gain | {rate(s.get('delay_named_gain'))} | 0 % | "
        f"{'met' if (s.get('delay_named_gain') or {}).get('hits', 0) == 0 else 'NOT met'} |",
        f"| true pair in the top two by the very candidates (the measure before families) | "
        f"{rate(s.get('pair_in_top2_exact'))} | (info) | |",
        f"| single effects below the floor reported 'none' | "
        f"{rate(s['single_below_floor_none'])} | (info) | |",
        f"| out-of-library effects not attributed ('unexplained' or 'none') | "
        f"{rate(s['outside_not_attributed'])} | (info) | |",
        "",
        "| effect (single, above floor) | cases | top-1 | top-1 or tie | verdicts |",
        "|---|---|---|---|---|",
    ]
    for name, d in sorted(s["per_effect_single"].items()):
        v = ", ".join(f"{k} {n}" for k, n in sorted(d["verdicts"].items(), key=lambda x: -x[1]))
        lines.append(f"| {name} | {d['n']} | {d['top1']} | {d['top1_or_tie']} | {v} |")
    return "\n".join(lines) + "\n"


def check_generator_flags(args: argparse.Namespace) -> None:
    """Refuse a flag given to a generator it does not apply to (it would be ignored, and
    the run would measure other cases than asked)."""
    from bench import BenchError
    if args.identify and (args.generator != "independent" or args.controller != "own"):
        raise BenchError("--identify is for --generator independent --controller own")
    for flag, given in (("--only", args.only), ("--indie-set", args.indie_set)):
        if given and args.generator != "independent":
            raise BenchError(f"{flag} is for --generator independent")
    if args.build_seed is not None:
        from bench.cli.options import SEED_RANGE
        from bench.gap.finalcheck import LOWEST_BUILD_SEED, highest_build_seed
        if args.generator != "final-check":
            raise BenchError("--build-seed is for --generator final-check")
        top = highest_build_seed(SEED_RANGE[1])
        if not LOWEST_BUILD_SEED <= args.build_seed <= top:
            # its noise seeds would be negative or past what a --seed may be
            raise BenchError(f"--build-seed must be {LOWEST_BUILD_SEED} to {top}, "
                             f"not {args.build_seed}")
    if args.generator == "final-check" and (args.effects or args.controller != "ecu"):
        raise BenchError("the final check runs its fixed cases with the whole library under "
                         "the bench's ECU: --effects and --controller do not apply")


def check_arguments(args: argparse.Namespace) -> list | None:
    """Refuse, before minutes of work, what the benchmark cannot run or write (the
    effects library asked for is returned)."""
    from bench import BenchError
    from bench.cli.outputs import check_output_file
    if args.cases < 1:
        raise BenchError("--cases must be >= 1")
    if args.workers < 1:
        raise BenchError("--workers must be >= 1")
    if not 2.0 <= args.log_s <= 120.0:
        raise BenchError("--log-s must be between 2 and 120 s")
    from bench.gap import effects as E
    if args.effects is not None and not args.effects.strip(", "):
        raise BenchError("--effects lists no effect")
    lib = E.parse_list(args.effects) if args.effects else None
    check_generator_flags(args)
    for flag, path in (("--json", args.json), ("--markdown", args.markdown)):
        if path:
            check_output_file(path, flag)
    return lib


def run(args: argparse.Namespace) -> int:
    from bench import BenchError
    from bench.gap.blind import run as bench_run
    lib = check_arguments(args)
    if args.generator == "final-check":
        from bench.gap import finalcheck as FC
        out = FC.run(args.workers, args.log_s, progress=sys.stderr.isatty(),
                     scheduler=args.scheduler,
                     first=FC.BUILD_SEEDS[0] if args.build_seed is None else args.build_seed)
    elif args.generator == "independent":
        from bench.gap.indiebench import NOMINAL, POOL
        if args.only and args.only not in POOL:
            raise BenchError(f"--only: unknown effect {args.only!r}; injected: {', '.join(POOL)}")
        from bench.gap.indiebench import run as indie_run
        try:
            actuator = NOMINAL.with_assignments(args.indie_set)
        except ValueError as exc:
            raise BenchError(f"--indie-set: {exc}") from None
        out = indie_run(args.cases, args.seed, args.workers, args.log_s,
                        progress=sys.stderr.isatty(), effects=lib, controller=args.controller,
                        actuator=actuator, scheduler=args.scheduler,
                        identify=args.identify, only=args.only)
    else:
        out = bench_run(args.cases, args.seed, args.workers, args.fidelity, args.log_s,
                        progress=sys.stderr.isatty(), effects=lib, scheduler=args.scheduler)
    md = markdown(out)
    print(md)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1, default=str))
    if args.markdown:
        Path(args.markdown).write_text(md)
    return 0
