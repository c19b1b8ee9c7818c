"""The actuator's identity: the serial number in object 0x1018 sub 4, set per
plant, served by the node's SDO server, refused outside UNSIGNED32."""

from __future__ import annotations

import argparse
import threading
import uuid

import can
import canopen
import pytest

from ema_contract.frames import load_od
from ema_contract.states import Pace
from plant_rt.cli import serial_arg
from plant_rt.node import PlantNode
from plant_rt.params import PlantParams


def _serial_read(serial: int | None) -> int:
    chan = f"id-{uuid.uuid4().hex}"
    nbus = can.Bus(interface="virtual", channel=chan)
    bus = can.Bus(interface="virtual", channel=chan)
    node = PlantNode(nbus, PlantParams(), pace=Pace.SYNC, serial=serial)
    th = threading.Thread(target=node.run, daemon=True)
    th.start()
    net = canopen.Network(bus)
    remote = canopen.RemoteNode(0x10, load_od())
    net.add_node(remote)
    remote.sdo.RESPONSE_TIMEOUT = 1.0
    net.notifier = can.Notifier(bus, net.listeners, timeout=0.02)
    try:
        assert remote.sdo[0x1018][2].raw == 1          # product code, from the EDS
        return int(remote.sdo[0x1018][4].raw)
    finally:
        node.stop()
        th.join(2.0)
        net.notifier.stop(1.0)
        bus.shutdown()
        nbus.shutdown()


def test_the_node_serves_its_serial_number():
    assert _serial_read(0xDEADBEEF) == 0xDEADBEEF
    assert int(load_od()[0x1018][4].default) == 0       # the default: the EDS's


def test_serial_numbers_outside_unsigned32_are_refused():
    assert serial_arg("0x10") == 16
    for bad in ("-1", "4294967296", "abc"):
        with pytest.raises(argparse.ArgumentTypeError):
            serial_arg(bad)
    with pytest.raises(ValueError, match="UNSIGNED32"):
        PlantNode(can.Bus(interface="virtual", channel=f"id-{uuid.uuid4().hex}"),
                  serial=2 ** 32)
