"""Two checks of the gap diagnosis on the bench's own plant (docs/gap-results.md).

    python benchmarks/gap_checks.py [--intervals SEEDS] [--offset SEEDS] [--json OUT]

- `--intervals 100-113`: the demo's worn actuator (backlash 50 um, friction x2.5) on the
  2 Hz sine, 10 periods, at full fidelity with sensor noise, one log per noise seed:
  the pair backlash+friction fitted (fast), then refined against the full-fidelity model
  (`bench.gap.refine`), each with its 95 % interval; how many intervals hold the truth.
- `--offset 31-33`: a log-side current offset of 0.4 A (the logger's current sensor, not
  the drive's: `sensors.current_in_loop` false) on the diagnosis manoeuvre, 10 s, full
  fidelity with noise: the whole diagnosis, its verdict and the offset it finds.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def seeds(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def intervals(seed_list: list[int]) -> list[dict]:
    from bench.gap.fit import fit
    from bench.gap.problem import build
    from bench.gap.refine import refine
    from bench.profiles.catalog import make_profile
    from bench.sim.harness import simulate
    from plant_rt.params import PlantParams
    prof = make_profile("sine", cycles=10)
    rows = []
    for s in seed_list:
        par = PlantParams().with_dict({"sensors.noise": True, "sensors.noise_seed": s,
                                       "effects.backlash_m": 50e-6,
                                       "effects.friction_scale": 2.5})
        p = build(simulate(prof, par).measured(), PlantParams(), 0.5)
        f = fit(p, ["backlash", "friction"])
        g, _ = refine(p, f)
        row = {"seed": s}
        for tag, x in (("fast", f), ("refined", g)):
            lo, hi = x.ci95[1]["friction_scale"]
            row[tag] = {"friction": x.theta[1]["friction_scale"], "ci95": [lo, hi],
                        "holds": lo <= 2.5 <= hi, "backlash_um": x.theta[0]["backlash_m"] * 1e6}
        rows.append(row)
        print(f"seed {s}: fast {row['fast']['friction']:.3f} {row['fast']['ci95']}, refined "
              f"{row['refined']['friction']:.3f} {row['refined']['ci95']}", flush=True)
    return rows


def offset(seed_list: list[int]) -> list[dict]:
    from bench.gap.diagnose import Options, diagnose
    from bench.gap.result_json import chosen_entry
    from bench.profiles.maneuvers import excitation
    from bench.sim.harness import simulate
    from plant_rt.params import PlantParams
    rows = []
    for s in seed_list:
        par = PlantParams().with_dict({"sensors.noise": True, "sensors.noise_seed": s,
                                       "sensors.current_in_loop": False,
                                       "sensors.current_offset_a": 0.4})
        js = diagnose(simulate(excitation(10.0), par).measured(),
                      options=Options(workers=1)).json()
        c = chosen_entry(js) or {}
        vals = {k: v["value"] for k, v in (c.get("params") or {}).items()}
        rows.append({"seed": s, "verdict": js["verdict"],
                     "finding": (js.get("finding") or {}).get("line"), "params": vals})
        print(f"seed {s}: {js['verdict']}: {rows[-1]['finding']}", flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--intervals", metavar="A-B")
    ap.add_argument("--offset", metavar="A-B")
    ap.add_argument("--json", metavar="OUT")
    a = ap.parse_args()
    out = {}
    if a.intervals:
        out["intervals"] = intervals(seeds(a.intervals))
        for tag in ("fast", "refined"):
            n = sum(r[tag]["holds"] for r in out["intervals"])
            print(f"{tag}: the truth inside {n} of {len(out['intervals'])} intervals")
    if a.offset:
        out["offset"] = offset(seeds(a.offset))
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
