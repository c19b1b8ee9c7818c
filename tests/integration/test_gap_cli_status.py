"""`bench gap`'s status lines go through `tqdm.write`, so that they land above the fits'
progress bar instead of breaking it (a bare print to stderr split the bar in two)."""

from __future__ import annotations

from bench.gap.resim import FAST
from bench.profiles.maneuvers import compact
from bench.sim.harness import simulate
from plant_rt.params import PlantParams


def test_status_lines_are_written_through_tqdm(tmp_path, monkeypatch):
    import tqdm

    from bench.cli import main
    base = PlantParams().with_dict({**FAST, "sensors.noise": True, "sensors.noise_seed": 4,
                                    "effects.backlash_m": 40e-6})
    simulate(compact(), base).measured().save(tmp_path / "worn.npz")
    written: list[str] = []
    real = tqdm.tqdm.write
    monkeypatch.setattr(tqdm.tqdm, "write",
                        classmethod(lambda cls, s, *a, **k: (written.append(s),
                                                             real(s, *a, **k))[1]))
    assert main(["gap", str(tmp_path / "worn.npz"), "--effects", "backlash,friction",
                 "--workers", "1"]) == 0
    assert any(s.startswith("gap: fitting") for s in written), written
    assert any(s.startswith("gap: done in") for s in written), written
