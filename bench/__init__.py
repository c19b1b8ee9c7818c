"""The ECU and operator side of the EMA ball-screw HUMS bench.

`bench` holds the position/speed controller, the in-process harness, the HUMS monitor,
the sim-to-real gap diagnosis, log tools and the `bench` command. It reaches the live
plant only through the CAN bus (see `bench.bus`); offline studies use the public
model API of `plant_rt`.
"""

__version__ = "0.1.0"


class BenchError(Exception):
    """An error the user can fix: printed as one line ``error: ...`` by the CLI."""


def machine_description() -> str:
    """CPU model, core count and Python version, for benchmark and report headers."""
    import os
    import platform
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def refuse_mf4_import() -> None:
    """python-can imports asammdf (its MF4 log format) with `import can`, ~0.6 s of a
    process's start-up; a process that reads and writes no log file refuses that import
    (the documented `sys.modules[name] = None`), in this process only: the loopback hub
    (`bench.bus`) and `bench up/status/down/plant` (`bench.cli`). `python -m plant_rt`
    does the same for itself (plant_rt does not import bench)."""
    import sys
    if "asammdf" not in sys.modules:
        sys.modules["asammdf"] = None  # type: ignore[assignment]
