"""Inputs several integration tests build alike: the Cranfield sample's tables imported
one trace per cycle (`import_cycles`), its healthy baseline (`cranfield_baseline`), both
in one folder (`cranfield_folder`), and a healthy and a worn noisy 2 Hz sine
(`sine_logs`)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "tests" / "data" / "cranfield_sample"
MAP = ROOT / "bench" / "rig" / "actuators" / "cranfield_map.json"
HEALTHY = "normal_load40_runs1-4.csv.xz"
SPALLING = "spalling5_load40_runs1-2.csv.xz"


def import_cycles(table: str, out: Path) -> None:
    """`bench import` of the sample's `table`: one trace per load, run and cycle in `out`."""
    from bench.cli import main
    assert main(["import", str(SAMPLE / table), "--map", str(MAP), "--split-by",
                 "load,run,group", "-o", str(out)]) == 0


def cranfield_baseline(out: Path) -> Path:
    """`bench rig baseline` of the healthy table's runs 1 and 2, written to `out`."""
    from bench.cli import main
    assert main(["rig", "baseline", str(SAMPLE / HEALTHY), "--runs", "1,2", "--actuator",
                 "cranfield", "--out", str(out)]) == 0
    return out


def cranfield_folder(d: Path) -> Path:
    """`d` with the healthy table's cycles in n/, the spalling table's in s/ and the
    healthy baseline of runs 1 and 2 as base.json."""
    import_cycles(HEALTHY, d / "n")
    import_cycles(SPALLING, d / "s")
    cranfield_baseline(d / "base.json")
    return d


def sine_logs(d: Path) -> Path:
    """healthy.npz and worn.npz (backlash 50 um, friction x2.5) in `d`: 3 cycles of the
    2 Hz sine, sensor noise on (seed 3), the measured columns only."""
    from bench.profiles.catalog import make_profile
    from bench.sim.harness import simulate
    from plant_rt.params import PlantParams
    for name, vals in (("healthy", {}), ("worn", {"effects.backlash_m": 50e-6,
                                                  "effects.friction_scale": 2.5})):
        p = PlantParams().with_dict({**vals, "sensors.noise": True, "sensors.noise_seed": 3})
        simulate(make_profile("sine", cycles=3), p).measured().save(d / f"{name}.npz")
    return d
