"""The one check of a CLI error in-process: exit 2 and one `error: ...` line on standard
error holding the given words (shared by the unit and integration tests)."""

from __future__ import annotations


def one_line(capsys, rc: int, *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert err.startswith("error: ") and len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


def stub_steps(monkeypatch, steps: tuple[tuple[str, str], ...], error: BaseException) -> None:
    """Replace each long step (module path, function name) by one that raises `error`: a
    test of what a command checks before its work sees the work start as that error."""
    import importlib

    def stub(*a, **k):
        raise error
    for module, name in steps:
        monkeypatch.setattr(importlib.import_module(module), name, stub)
