"""Seeds derived from a user's seed fold into the seed parameters' range
(`plant_rt.paramvalues.seed_in_range`): `bench fleet synth --seed 3000` derived noise seeds of
3e9 and ended in "sensors.noise_seed ... is above its maximum"."""

from __future__ import annotations

import json

from plant_rt.params import PlantParams
from plant_rt.paramvalues import SEED_MAX, seed_in_range


def test_a_seed_in_range_is_unchanged_and_a_larger_one_folds():
    assert seed_in_range(0) == 0 and seed_in_range(12345) == 12345
    assert seed_in_range(SEED_MAX - 1) == SEED_MAX - 1
    big = 3000 * 1_000_003 + 7
    assert 0 <= seed_in_range(big) < SEED_MAX
    PlantParams().with_dict({"sensors.noise_seed": seed_in_range(big)})   # accepted


def test_fleet_synth_takes_a_seed_above_2147(tmp_path, capsys):
    from bench.cli import main
    out = tmp_path / "syn"
    assert main(["fleet", "synth", "--actuators", "1", "--days", "1", "--workers", "1",
                 "--seed", "3000", "--out", str(out)]) == 0
    truth = json.loads((out / "fleet-truth.json").read_text())
    assert truth["seed"] == 3000 and len(list(out.rglob("*.log"))) == 1
