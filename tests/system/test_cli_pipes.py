"""`bench` as a Unix tool in a pipe: a reader that goes away (`bench rig assess ... | head
-1`) ends the command quietly with 141 (as SIGPIPE would), never a traceback or an
`error:` line; light commands (`bench down`) do not load python-can's MF4 support."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SAMPLE = Path(__file__).resolve().parents[1] / "data" / "cranfield_sample"


def test_a_closed_pipe_ends_the_command_quietly(tmp_path):
    from bench.cli import main
    base = tmp_path / "base.json"
    assert main(["rig", "baseline", str(SAMPLE / "normal_load40_runs1-4.csv.xz"), "--runs",
                 "1,2", "--lead-mm", "5", "--out", str(base)]) == 0
    proc = subprocess.Popen(
        [sys.executable, "-c", "from bench.cli import main; raise SystemExit(main())", "rig",
         "assess", str(SAMPLE / "spalling5_load40_runs1-2.csv.xz"), "--baseline", str(base)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None
    proc.stdout.close()                 # the reader is gone before the first line
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 141, err
    assert b"Traceback" not in err and b"error:" not in err and b"Exception" not in err


def test_bench_down_does_not_import_mf4_support(tmp_path):
    env = {"BENCH_STATE_DIR": str(tmp_path / "state"), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-X", "importtime", "-c",
                          "import sys; sys.argv = ['bench', 'down']; "
                          "from bench.cli import main; raise SystemExit(main())"],
                         capture_output=True, text=True, timeout=60, env=env)
    assert out.returncode == 0 and "nothing to stop" in out.stdout + out.stderr
    mods = {line.rsplit("|", 1)[1].strip() for line in out.stderr.splitlines()
            if line.startswith("import time:")}
    assert "can" in mods and "asammdf.blocks" not in mods


def _candump(path, n: int = 40) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "unit"))
    from log_frames import run, write_log
    write_log(str(path), run(n))


def test_candump_on_standard_input_decodes_to_csv_on_standard_output(tmp_path):
    """`cat log | bench decode -` said "unknown log format '(no suffix)'", and `-o -` was
    refused: candump -L on stdin, CSV on stdout, the summary on stderr."""
    log = tmp_path / "run.log"
    _candump(log)
    out = subprocess.run([sys.executable, "-m", "bench", "decode", "-", "-o", "-"],
                         input=log.read_bytes(), capture_output=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.decode().splitlines()
    assert lines[0].startswith("t_s,") and len(lines) == 41
    assert b"40 SYNC periods" in out.stderr


def test_stdin_and_formats_in_process(tmp_path, monkeypatch, capsys):
    """`-` with --format, a file without a suffix with --format, plain candump output
    with a hint to use -L."""
    import io

    from bench.cli import main
    log = tmp_path / "run.log"
    _candump(log)
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(log.read_bytes())))
    assert main(["decode", "-", "--format", "log", "-o", str(tmp_path / "t.csv")]) == 0
    assert (tmp_path / "t.csv").read_text().count("\n") == 41
    noext = tmp_path / "dump"
    noext.write_bytes(log.read_bytes())
    capsys.readouterr()
    assert main(["decode", str(noext)]) == 2
    assert "name the format with --format" in capsys.readouterr().err
    assert main(["decode", str(noext), "--format", "log"]) == 0
    plain = b"  can0  080   [1]  01\n  can0  190   [6]  7E 00 00 00 40 00\n"
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(plain)))
    capsys.readouterr()
    assert main(["decode", "-"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "record the log with `candump -L`" in err


def test_a_log_read_from_standard_input_leaves_no_unclosed_file_at_exit(tmp_path):
    """The spool that holds standard input (so a log on stdin can be read twice) was left
    open until the interpreter ended, which printed "ResourceWarning: Unclosed file
    <tempfile.SpooledTemporaryFile ...>" under -X dev and at the end of the suite."""
    log = tmp_path / "run.log"
    _candump(log)
    out = subprocess.run([sys.executable, "-X", "dev", "-W", "always::ResourceWarning",
                          "-m", "bench", "decode", "-", "-o", str(tmp_path / "run.csv")],
                         input=log.read_bytes(), capture_output=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert len((tmp_path / "run.csv").read_text().splitlines()) == 41
    assert b"ResourceWarning" not in out.stderr, out.stderr.decode()


def test_a_compressed_log_on_standard_input_is_decompressed(tmp_path):
    """`cat run.log.gz | bench decode -` read gzip's bytes as candump lines: "nothing to
    decode". A gzip, xz or bzip2 stream on standard input is known by its first bytes."""
    import bz2
    import gzip
    import lzma
    log = tmp_path / "run.log"
    _candump(log)
    plain = subprocess.run([sys.executable, "-m", "bench", "decode", "-", "-o", "-"],
                           input=log.read_bytes(), capture_output=True, timeout=120)
    assert plain.returncode == 0, plain.stderr
    for pack in (gzip.compress, lzma.compress, bz2.compress):
        out = subprocess.run([sys.executable, "-m", "bench", "decode", "-", "-o", "-"],
                             input=pack(log.read_bytes()), capture_output=True, timeout=120)
        assert out.returncode == 0 and out.stdout == plain.stdout, (pack, out.stderr)
    cut = gzip.compress(log.read_bytes())
    out = subprocess.run([sys.executable, "-m", "bench", "decode", "-"],
                         input=cut[: len(cut) // 2], capture_output=True, timeout=120)
    err = out.stderr.decode().strip()
    assert out.returncode == 2 and err.startswith("error: standard input: cannot "
                                                  "decompress") and "\n" not in err, err
