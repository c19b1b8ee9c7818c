"""The lines of a text file as the bench's readers read them: a table's
(`bench.signals.tables`), a map's (`bench.gap.importer`) and a trends file's
(`bench.hums.trend_io`): decompressed, decoded as UTF-8 line by line, every fault a
one-line `BenchError` naming the file and the offset."""

from __future__ import annotations

import bz2
import codecs
import gzip
import io
import lzma
import os
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from bench import BenchError

COMPRESSED: dict[str, Any] = {".xz": lzma.open, ".gz": gzip.open, ".bz2": bz2.open}
MAX_LINE_BYTES = 1 << 20
"""A text line longer than this is refused (no rig writes such rows; a binary file read
as text would otherwise be one line of its whole size)."""
BAR_BYTES = 16 << 20
"""Files at least this large show a progress bar while they are read."""


class TextLines:
    """The lines of a text file (decompressed when it ends in .xz, .gz or .bz2: a table's
    by default, another's when `compressed`) as read, with a bar on a large one (`bar`),
    decoded as UTF-8 (a byte-order mark at its start dropped); a directory, an
    unreadable, corrupt or non-UTF-8 file, a line over MAX_LINE_BYTES is a one-line
    BenchError naming the file. `head` reads ahead without losing those lines."""

    def __init__(self, path: Path, what: str, compressed: bool | None = None,
                 bar: bool = True) -> None:
        self.path, self.what = path, what
        self.offset = 0
        self.ahead: list[str] = []
        self.show_bar = bar
        opener = (COMPRESSED.get(path.suffix.lower())
                  if (what == "table" if compressed is None else compressed) else None)
        self.compressed = opener is not None
        try:
            self.raw = open(path, "rb")  # noqa: SIM115 - closed in __exit__
        except IsADirectoryError:
            raise BenchError(f"{path}: is a directory, not a {what} file") from None
        except OSError as exc:
            raise BenchError(f"{path}: cannot be read ({exc.strerror or exc})") from None
        self.fh: Any = (io.BufferedReader(opener(self.raw, "rb"), 1 << 20) if opener is not None
                        else self.raw)
        self.size = os.fstat(self.raw.fileno()).st_size
        self.bar: Any = None

    def __enter__(self) -> TextLines:
        if self.show_bar and self.size >= BAR_BYTES:
            from tqdm import tqdm
            self.bar = tqdm(total=self.size, unit="B", unit_scale=True,
                            desc=f"reading {self.path.name}", leave=False)
        return self

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.close()
        self.fh.close()
        self.raw.close()

    def head(self, chars: int) -> str:
        """The first lines up to about `chars` characters (kept for the iteration)."""
        it = self._read()
        n = 0
        for line in it:
            self.ahead.append(line)
            n += len(line)
            if n >= chars:
                break
        self._rest = it
        return "".join(self.ahead)

    def __iter__(self) -> Iterator[str]:
        yield from self.ahead
        self.ahead = []
        yield from getattr(self, "_rest", None) or self._read()

    def _read(self) -> Iterator[str]:
        n = 0
        while True:
            raw = self._readline()
            if not raw:
                return
            if self.offset == 0 and raw.startswith(codecs.BOM_UTF8):
                raw, self.offset = raw[3:], 3
            try:
                line = raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise BenchError(
                    f"{self.path}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset "
                    f"{self.offset + exc.start}); a {self.what} file must be UTF-8 text"
                    + (" (or Parquet)" if self.what == "table" else "")) from None
            self.offset += len(raw)
            n += 1
            if self.bar is not None and n % 65536 == 0:
                self.bar.update(self.raw.tell() - self.bar.n)
            yield line

    def _readline(self) -> bytes:
        try:
            raw: bytes = self.fh.readline(MAX_LINE_BYTES + 1)
        except (OSError, EOFError, ValueError, lzma.LZMAError, zlib.error) as exc:
            if not self.compressed:
                raise BenchError(f"{self.path}: cannot be read ({exc})") from None
            raise BenchError(f"{self.path}: cannot decompress ({type(exc).__name__}: "
                             f"{exc}); is it a complete {self.path.suffix} file?") from None
        if len(raw) > MAX_LINE_BYTES:
            raise BenchError(f"{self.path}: a line longer than {MAX_LINE_BYTES} bytes at "
                             f"offset {self.offset}: not a {self.what} of text rows")
        return raw


def read_text(path: Path, what: str) -> str:
    """A (small) text file's content, by the rules of `TextLines`."""
    with TextLines(path, what) as lines:
        return "".join(lines)
