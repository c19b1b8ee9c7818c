"""Test layout by cost: tests/unit (fast, in-process), tests/integration (processes,
bus, long physics) and tests/system (the built wheel in a clean virtual environment).
Markers come from the path, so `-m unit` / `-m integration` / `-m system` select them
(PyBaMM's conftest does the same)."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        parts = Path(str(item.fspath)).parts
        if "unit" in parts:
            item.add_marker(pytest.mark.unit)
        elif "integration" in parts:
            item.add_marker(pytest.mark.integration)
        elif "system" in parts:
            item.add_marker(pytest.mark.system)
