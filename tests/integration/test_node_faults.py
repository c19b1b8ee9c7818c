"""The plant node against a flood over the bus (item 8): a bounded burst of
alternating valid and short RPDOs from one client gives one EMCY per inhibit time
(0x1015, 100 ms), every bad frame counted, every repeat accounted for."""

from __future__ import annotations

import time

import can
import canopen
import pytest
from bus_helpers import BUS_KINDS, Collector, module_bus_env, wait_until

from ema_contract.frames import Frames, load_od
from ema_contract.states import NMTCommand
from ema_contract.transport import close_bus

PAIRS = 1000


@pytest.fixture(scope="module", params=BUS_KINDS)
def bus_env(request, tmp_path_factory):
    yield from module_bus_env(request, tmp_path_factory)


def test_rpdo_flood_gives_one_emcy_per_inhibit_time(bus_env):
    f = Frames()
    watch = Collector(bus_env)
    network = canopen.Network(bus_env.bus())
    network.notifier = can.Notifier(network.bus, network.listeners, timeout=0.05)
    node = canopen.RemoteNode(0x10, load_od())
    network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 1.0
    bus = network.bus
    try:
        node.nmt.send_command(NMTCommand.RESET_NODE)
        wait_until(lambda: [m for m in watch.msgs if m.arbitration_id == 0x710
                            and m.data[0] == 0], 2.0, "the boot-up")
        assert node.sdo[0x1015].raw == 1000                  # 100 ms
        valid = f.encode("EMA_RPDO1", {"CurrentDemand": 1.0, "ControlWord": 1})
        short = can.Message(arbitration_id=0x210, data=b"\x00\x00", is_extended_id=False)
        t0 = time.monotonic()
        for _ in range(PAIRS):
            bus.send(valid)
            bus.send(short)
        st = node.sdo["node_status"]
        wait_until(lambda: st["bad_frames"].raw == PAIRS, 20.0, "the flood to be processed")
        time.sleep(0.3)                 # the last waiting EMCY leaves after the inhibit time
        elapsed = time.monotonic() - t0
        emcy = [f.decode(m)[1] for m in watch.msgs if m.arbitration_id == 0x90]
        sent, suppressed = st["emcy_sent"].raw, st["emcy_suppressed"].raw
        print(f"{2 * PAIRS} frames in {elapsed:.2f} s: {len(emcy)} EMCY, "
              f"{suppressed} suppressed")
        assert len(emcy) == sent
        assert {f.label("EMA_EMCY", "EMCY_ErrorCode", e["EMCY_ErrorCode"])
                for e in emcy} == {"pdo_length"}
        assert 1 <= sent <= elapsed / 0.1 + 2
        assert sent + suppressed == PAIRS
    finally:
        node.nmt.send_command(NMTCommand.RESET_NODE)
        network.notifier.stop(1.0)
        close_bus(bus)
        watch.close()
