"""What `bench hums sweep|rul|campaign` write when asked (--figures, --json, --doc), in
order, with the simulations replaced by stand-ins: the figures' paths printed, the rows'
JSON, and the --doc section rewritten between its markers (the campaign's with links to its
figures), the rest of the page kept."""

from __future__ import annotations

import json
import types
from pathlib import Path

import pytest

from bench.cli import main


def _row(name: str) -> types.SimpleNamespace:
    return types.SimpleNamespace(id=name, quantity="q", thesis=1.0, project=1.0, ratio=1.0,
                                 to_json=lambda: {"id": name})


def _figures(res: object, folder: str) -> list[Path]:
    path = Path(folder) / "f.png"
    path.write_bytes(b"png")
    return [path]


def _fake(monkeypatch: pytest.MonkeyPatch, command: str) -> None:
    res = types.SimpleNamespace(points=[1], elapsed_s=0.0)
    markdown = lambda res, paths, doc_dir: f"{command} table {len(paths)}"  # noqa: E731
    if command == "sweep":
        from bench.hums import sweep as mod
        monkeypatch.setattr(mod, "run", lambda *a, **k: res)
        monkeypatch.setattr("bench.core.thesis_rows.check", lambda rows: [])
    elif command == "rul":
        from bench.hums import rul_run as mod
        monkeypatch.setattr(mod, "run_rul", lambda *a, **k: res)
    else:
        from bench.hums import campaign as mod
        monkeypatch.setattr(mod, "run_campaign", lambda *a, **k: res)
        monkeypatch.setattr(mod, "campaign_markdown", lambda res: "campaign table")
        monkeypatch.setattr(mod, "campaign_figure", _figures)
        monkeypatch.setattr(mod, "campaign_json", lambda res: [{"id": "C1"}])
        return
    monkeypatch.setattr(mod, "rows", lambda res: [_row("R1")])
    monkeypatch.setattr(mod, "figures", _figures)
    monkeypatch.setattr(mod, "markdown", markdown)


@pytest.mark.parametrize(("command", "section", "body", "data"), [
    ("sweep", "sweep", "sweep table 1", [{"id": "R1"}]),
    ("rul", "rul", "rul table 1", [{"id": "R1"}]),
    ("campaign", "campaign", "campaign table\n![f](figs/f.png)", [{"id": "C1"}]),
])
def test_outputs_written_in_order(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str], command: str,
                                  section: str, body: str, data: list[dict]) -> None:
    _fake(monkeypatch, command)
    figs, out, doc = tmp_path / "figs", tmp_path / "rows.json", tmp_path / "page.md"
    figs.mkdir()
    doc.write_text(f"# page\n\n<!-- {section}:begin -->\nold\n<!-- {section}:end -->\n\nend\n")
    rc = main(["hums", command, "--figures", str(figs), "--json", str(out), "--doc", str(doc),
               "--workers", "1"])
    assert rc == 0
    lines = capsys.readouterr().out.splitlines()
    wrote = [ln for ln in lines if ln.startswith(("wrote ", "updated "))]
    assert wrote == [f"wrote {figs / 'f.png'}", f"wrote {out}", f"updated {doc}"]
    assert json.loads(out.read_text()) == data
    assert doc.read_text() == (f"# page\n\n<!-- {section}:begin -->\n{body}\n"
                               f"<!-- {section}:end -->\n\nend\n")
