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
