"""`bench demo`: the bench's main job on its embedded defaults, no hardware needed.

Three runs of the thesis' closed-loop 2 Hz sine (H4) over the CAN bus, each logged
in candump format: a healthy actuator, a worn one (backlash 50 um, friction x2.5) and
one at the end of its life (backlash 100 um, friction x4), as the degradation sweep of
chapter 6 defines them. The HUMS then reads the three logs, as it would logs from a real
actuator: Cp/Ci/peak-ratio indexes against the monitoring model, the current spectrum,
a verdict per log and an HTML report; and the gap diagnosis names what the worn log
has that the nominal model lacks.

Bus: the configured one (flags, python-can's environment or config file, vcan0 where
the kernel has SocketCAN), else a loopback hub started for the run; `--in-process`
runs the same scenario without any bus (the compiled in-process harness).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from bench import BenchError
from bench.bus import bus_settings
from bench.cli import options as opt

# name, degradation d (0..1; backlash 100 d um, friction x(1 + 3 d)), noise seed
CASES: tuple[tuple[str, float, int], ...] = (("healthy", 0.0, 11), ("worn", 0.5, 12),
                                              ("end-of-life", 1.0, 13))


def add_subparser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo", help="the main job on embedded defaults: healthy, worn and failing "
        "actuator over the bus, HUMS report, gap diagnosis",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    opt.add_out(p, default="out/demo", help="where the logs, traces and reports go (default: %(default)s)")
    p.add_argument("--cycles", type=float, default=10.0, metavar="N",
                   help="sine periods per run, 2 Hz, 0.5 mm (default: %(default)g)")
    p.add_argument("--pace", choices=["sync", "realtime"], default="sync",
                   help="sync: lockstep, faster than real time (default); realtime: wall "
                        "clock, as against hardware")
    p.add_argument("--in-process", action="store_true",
                   help="no bus: run the plant and the ECU in this process")
    p.add_argument("--no-gap", action="store_true", help="skip the gap diagnosis")
    opt.add_bus(p)
    p.set_defaults(func=run)


def _values(d: float, seed: int) -> dict[str, Any]:
    """Plant parameter values of degradation d, the sweep's definition (chapter 6): what
    the degraded set changes from the defaults, by dotted name."""
    from bench.hums.sweep import degraded  # heavy (numba): imported when the demo runs
    from plant_rt.params import PlantParams  # imports the compiled plant: as above
    p = degraded(PlantParams(), d, noise=True, seed=seed)
    return {k: v for k, (v, _) in p.diff(PlantParams()).items()}


def _shown(values: dict[str, Any]) -> list[str]:
    """``NAME=VALUE`` as `bench run --set` would take them (for the screen and summary)."""
    return [f"{k}={v}" for k, v in values.items()]


def _run_case(name: str, values: dict[str, Any], cycles: float, out: Path,
              args: argparse.Namespace, say) -> Path:
    # the imports below are heavy (numba): made when the demo runs, not at `bench --help`
    from bench.profiles.catalog import make_profile
    from plant_rt.params import PlantParams
    profile = make_profile("sine", cycles=cycles)
    params = PlantParams().with_dict(values)
    if args.in_process:
        from bench.sim.harness import simulate
        trace = simulate(profile, params)
        path = out / f"{name}.npz"
        trace.save(path)
        return path
    from bench.ecu import run_over_bus
    path = out / f"{name}.log"
    trace = run_over_bus(profile, values=values, pace=args.pace, log_path=path,
                         progress=sys.stderr.isatty(), settings=bus_settings(args),
                         announce=say if name == CASES[0][0] else None)
    trace.save(out / f"{name}.npz")
    # a plant already on the bus (`bench up --set ...`) keeps its own start-up values for
    # what the demo does not set: say so rather than pass them off as the defaults
    other = PlantParams.from_dict(trace.meta["params"]).diff(params)
    if other:
        say(f"warning: the plant on this bus ran {name} with non-default "
            f"{', '.join(sorted(other))}; restart it without --set for the embedded defaults")
    return path


def _finite(v):
    """JSON-safe copy: non-finite floats become null."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x) for x in v]
    return v


def run(args: argparse.Namespace) -> int:
    from plant_rt.params import PlantParams  # the compiled plant: not at `bench --help`
    if not (math.isfinite(args.cycles) and 1 <= args.cycles <= 1000):
        raise BenchError("--cycles must be within 1..1000")
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BenchError(f"--out {out}: {exc.strerror}") from None

    def say(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    t_all = time.perf_counter()
    where = "in process (no bus)" if args.in_process else f"over the bus, pace {args.pace}"
    print(f"bench demo: H4 sine 0.5 mm 2 Hz x {args.cycles:g} periods, {where}")
    logs: list[Path] = []
    for i, (name, d, seed) in enumerate(CASES, 1):
        t0 = time.perf_counter()
        values = _values(d, seed)
        shown = ", ".join(s for s in _shown(values) if not s.startswith("sensors.noise_seed"))
        print(f"[{i}/{len(CASES)}] {name}: {shown or 'nominal'}", flush=True)
        logs.append(_run_case(name, values, args.cycles, out, args, say))
        print(f"      {logs[-1]} ({time.perf_counter() - t0:.1f} s)", flush=True)

    print("HUMS: indexes against the monitoring model, verdicts, report", flush=True)
    from bench.hums.report import write_report  # heavy, as above
    from bench.hums.verdict import judged_ci
    t0 = time.perf_counter()
    page, analyses = write_report([str(p) for p in logs], out / "hums", PlantParams(),
                                  rul=False, progress=False)
    rows = []
    print(f"  {'log':16s} {'verdict':9s} {'Cp':>7s} {'Ci':>7s} {'peak ratio':>10s} "
          f"{'lost motion um':>14s}")
    for a in analyses:
        ix = a.indexes
        ci = judged_ci(ix.ci, ix.ci_harmonic)
        lm = ix.lost_motion_m * 1e6 if math.isfinite(ix.lost_motion_m) else float("nan")
        print(f"  {a.name:16s} {a.verdict.name:9s} {ix.cp:7.3f} {ci:7.3f} {ix.peak_ratio:10.2f} "
              f"{lm:14.1f}")
        rows.append({"log": a.name, "verdict": a.verdict.name, "cp": ix.cp, "ci": ci,
                     "ci_broadband": ix.ci,
                     "peak_ratio": ix.peak_ratio, "lost_motion_um": lm,
                     "reasons": a.reasons})
    print(f"  report: {page} ({time.perf_counter() - t0:.1f} s)")

    gap = None
    if not args.no_gap:
        print("gap diagnosis of the worn log against the nominal model", flush=True)
        # heavy, and skipped with --no-gap
        from bench.gap.diagnose import Options, diagnose
        from bench.gap.inputs import load_log
        from bench.gap.report import write_report as gap_report
        from bench.gap.summary import text
        t0 = time.perf_counter()
        res = diagnose(load_log(str(logs[1])), None, None,
                       Options(workers=2, progress=sys.stderr.isatty()))
        gap = res.json()
        print("  " + text(gap).replace("\n", "\n  "))
        from bench.gap.result_json import gap_document, model_gap_verdict
        doc = gap_document(str(logs[1]), "model",
                           model_gap_verdict(gap, "thesis model (nominal values)"), gap,
                           round(time.perf_counter() - t0, 3))
        idx = gap_report(res, gap, out / "gap", doc)
        (out / "gap" / "diagnosis.json").write_text(json.dumps(_finite(gap), indent=1))
        print(f"  report: {idx} ({time.perf_counter() - t0:.1f} s)")

    (out / "summary.json").write_text(json.dumps(_finite(
        {"cases": [{"name": n, "degradation": d, "assignments": _shown(_values(d, s))}
                   for n, d, s in CASES],
         "hums": rows, "gap": gap, "wall_s": time.perf_counter() - t_all}),
        indent=1, allow_nan=False))
    print(f"done in {time.perf_counter() - t_all:.1f} s; everything is in {out}/")
    return 0
