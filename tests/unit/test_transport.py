"""Transport selection (flags > python-can configuration > vcan0 > hub) and the
loopback hub's protocol, with python-can-remote's own client."""

from __future__ import annotations

import os
import socket
import tempfile
import time

import can
import pytest
from bus_helpers import thread_hub

from ema_contract import transport as T


@pytest.fixture
def clean_env(monkeypatch, tmp_path):
    for k in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))          # no ~/.canrc
    monkeypatch.setenv(T.STATE_ENV, str(tmp_path / "state"))
    monkeypatch.setattr(T, "socketcan_works", lambda channel="vcan0": False)
    monkeypatch.setattr(can, "rc", {})
    return tmp_path


def test_nothing_configured(clean_env):
    assert T.resolve({}) is None


def test_environment_then_flags(clean_env, monkeypatch):
    monkeypatch.setenv("CAN_INTERFACE", "virtual")
    monkeypatch.setenv("CAN_CHANNEL", "envchan")
    cfg, source = T.resolve({})
    assert (cfg["interface"], cfg["channel"], source) == ("virtual", "envchan",
                                                         "python-can configuration")
    cfg, _ = T.resolve({"channel": "flagchan"})
    assert cfg["channel"] == "flagchan"
    monkeypatch.setenv("CAN_CONFIG", '{"bitrate": 500000}')
    assert T.resolve({})[0]["bitrate"] == 500000


def test_config_file(clean_env):
    (clean_env / ".canrc").write_text("[default]\ninterface = virtual\nchannel = filechan\n")
    cfg, _ = T.resolve({})
    assert cfg["channel"] == "filechan"


def test_unknown_interface_is_reported(clean_env, monkeypatch):
    monkeypatch.setenv("CAN_INTERFACE", "nonsense")
    with pytest.raises(T.BusUnavailable):
        T.resolve({})


def test_vcan0_then_hub(clean_env, monkeypatch):
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    port = srv.getsockname()[1]
    try:
        T.write_state(T.HUB_FILE, {"pid": os.getpid(), "port": port})
        cfg, source = T.resolve({})
        assert cfg == {"interface": "remote", "channel": f"ws://127.0.0.1:{port}/"}
        assert source == f"loopback hub of the bench in {T.state_dir()}"
        monkeypatch.setattr(T, "socketcan_works", lambda channel="vcan0": True)
        assert T.resolve({})[0] == {"interface": "socketcan", "channel": "vcan0"}
    finally:
        srv.close()
    T.write_state(T.HUB_FILE, {"pid": 999999999, "port": port})   # stale record
    monkeypatch.setattr(T, "socketcan_works", lambda channel="vcan0": False)
    assert T.resolve({}) is None


@pytest.fixture
def hub():
    with thread_hub() as h:
        yield h.url


def _bus(url, **kw):
    return T.open_bus({"interface": "remote", "channel": url}, **kw)


def test_hub_forwards_between_clients_with_echo_and_filters(hub):
    a = _bus(hub)
    b = _bus(hub, receive_own_messages=True)
    c = _bus(hub, can_filters=[{"can_id": 0x100, "can_mask": 0x700}])
    try:
        a.send(can.Message(arbitration_id=0x123, data=b"\x01\x02", is_extended_id=False))
        a.send(can.Message(arbitration_id=0x7FF, data=b"", is_extended_id=False))
        b.send(can.Message(arbitration_id=0x1ABCDEF0, data=bytes(8), is_extended_id=True))
        got_b = [b.recv(2.0) for _ in range(3)]
        assert [m.arbitration_id for m in got_b] == [0x123, 0x7FF, 0x1ABCDEF0]
        assert bytes(got_b[0].data) == b"\x01\x02" and got_b[2].is_extended_id
        assert c.recv(2.0).arbitration_id == 0x123          # only 0x1xx passes c's filter
        assert c.recv(0.2) is None
        m = a.recv(2.0)
        assert m.arbitration_id == 0x1ABCDEF0 and a.recv(0.2) is None   # no echo for a
    finally:
        for bus in (a, b, c):
            t0 = time.monotonic()
            bus.shutdown()
            assert time.monotonic() - t0 < 1.0               # close handshake answered


def test_hub_periodic_tasks(hub):
    a, b = _bus(hub), _bus(hub)
    try:
        task = a.send_periodic(can.Message(arbitration_id=0x321, data=b"\x07",
                                           is_extended_id=False), 0.01)
        time.sleep(0.2)
        task.stop()
        time.sleep(0.05)
        n = 0
        while b.recv(0.05) is not None:
            n += 1
        assert 10 <= n <= 30
    finally:
        a.shutdown()
        b.shutdown()


@pytest.fixture
def no_state_env(monkeypatch, tmp_path):
    """Neither $BENCH_STATE_DIR nor $XDG_RUNTIME_DIR; the temporary directory (and home)
    under `tmp_path`, so the test's state directory is its own."""
    monkeypatch.delenv(T.STATE_ENV, raising=False)
    monkeypatch.delenv("XDG_RUNTIME_DIR", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    return tmp_path


def test_state_dir_is_the_same_from_every_working_directory(no_state_env, monkeypatch):
    """Without $XDG_RUNTIME_DIR the state directory was ./.bench: `bench up` in one folder
    and `bench status` in another talked to two benches. Now it is one per user."""
    seen = set()
    for sub in ("a", "a/b", "c"):
        d = no_state_env / sub
        d.mkdir(parents=True, exist_ok=True)
        monkeypatch.chdir(d)
        seen.add(T.state_dir())
    assert len(seen) == 1, seen
    d = seen.pop()
    assert d == no_state_env / "tmp" / f"ema-bench-{os.getuid()}"
    st = os.lstat(d)
    assert st.st_mode & 0o777 == 0o700 and st.st_uid == os.getuid()
    monkeypatch.setenv(T.STATE_ENV, str(no_state_env / "mine"))   # still the override
    assert T.state_dir() == no_state_env / "mine"


def test_state_dir_refuses_a_temporary_directory_it_does_not_own(no_state_env, monkeypatch):
    """Anyone may create the name in a shared temporary directory first: a link (or a
    directory of another user) is not used; the state goes to ~/.cache/ema-bench."""
    target = no_state_env / "elsewhere"
    target.mkdir()
    (no_state_env / "tmp" / f"ema-bench-{os.getuid()}").symlink_to(target)
    assert T.state_dir() == no_state_env / "home" / ".cache" / "ema-bench"
    T.write_state(T.HUB_FILE, {"pid": os.getpid(), "port": 1234})
    assert not list(target.iterdir())
    assert os.lstat(T.state_dir()).st_mode & 0o777 == 0o700


def test_a_world_readable_own_state_dir_is_closed(no_state_env):
    d = no_state_env / "tmp" / f"ema-bench-{os.getuid()}"
    d.mkdir(mode=0o755)
    os.chmod(d, 0o755)
    assert T.state_dir() == d
    assert os.lstat(d).st_mode & 0o777 == 0o700
