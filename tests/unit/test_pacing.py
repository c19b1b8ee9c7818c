"""The absolute-deadline pacer and its lateness statistics (fake clock: deterministic)."""

from __future__ import annotations

import os

import pytest

from plant_rt.pacing import LatenessStats, RealtimePacer, use_normal_priority, use_realtime_priority


class FakeClock:
    def __init__(self) -> None:
        self.t = 0

    def __call__(self) -> int:
        self.t += 100            # every reading costs 100 ns: spins terminate
        return self.t


def test_stats_percentiles_in_microsecond_bins():
    s = LatenessStats()
    for us in range(100):
        s.add(us * 1000 + 500)
    assert s.count == 100
    assert s.percentile_us(50) == pytest.approx(50, abs=1)
    assert s.percentile_us(99) == pytest.approx(99, abs=1)
    assert s.max_us == pytest.approx(99.5)
    s.add(10**12)                # beyond the histogram: overflow bin, max kept
    assert s.max_us == 1e9
    s.reset()
    assert s.percentile_us(99) == 0.0


def test_releases_are_absolute_and_misses_counted():
    clock = FakeClock()
    p = RealtimePacer(1e-3, spin_s=200e-6, clock=clock)
    p.start()
    first = p.release_ns
    polled = []
    for _ in range(5):
        late = p.wait(lambda dt: (polled.append(dt), setattr(clock, "t", clock.t + int(dt * 1e9))))
        assert 0 <= late < 2000
        p.done()
    assert p.release_ns == first + 5 * 1_000_000     # no drift: k T from the start
    assert p.misses == 0 and polled
    # a period whose work overruns the next release is a deadline miss
    p.wait(lambda dt: setattr(clock, "t", clock.t + int(dt * 1e9)))
    clock.t += 1_500_000
    assert p.done() is True
    assert p.misses == 1 and p.last_missed


def test_long_stall_skips_instead_of_bursting():
    clock = FakeClock()
    p = RealtimePacer(1e-3, max_behind=50, clock=clock)
    p.start()
    p.wait()
    clock.t += 200_000_000                   # 200 ms stall
    p.done()
    assert p.skipped >= 150
    assert p.release_ns > clock.t - 2_000_000


def test_discipline_locks_the_phase_to_an_event_slowly():
    clock = FakeClock()
    p = RealtimePacer(1e-3, clock=clock)
    p.start()
    base = p.release_ns
    # events 0.5 ms after our releases; target: release 0.3 ms after the event
    for k in range(200):
        event = base + k * 1_000_000 + 500_000
        step = p.discipline(event, 300_000)
        assert abs(step) <= 20_000
        p.release_ns += 1_000_000             # as done() would
        base_shift = (p.release_ns - (event + 300_000)) % 1_000_000
    assert min(base_shift, 1_000_000 - base_shift) < 2_000


def test_realtime_priority_is_applied_or_the_refusal_described():
    assert use_realtime_priority(0) == "normal scheduling"
    with pytest.raises(ValueError, match="1..99"):
        use_realtime_priority(100)
    before = os.sched_getscheduler(0)
    try:
        said = use_realtime_priority(3)
        if said.startswith("SCHED_FIFO"):
            assert said == "SCHED_FIFO priority 3"
            assert os.sched_getscheduler(0) == os.SCHED_FIFO
            assert os.sched_getparam(0).sched_priority == 3
        else:                                  # not permitted here: said, nothing changed
            assert "refused" in said and "CAP_SYS_NICE" in said
            assert os.sched_getscheduler(0) == before
    finally:
        use_normal_priority()
    assert os.sched_getscheduler(0) == os.SCHED_OTHER

