"""Reading a Tekscan export as a stream: the header first, then blocks of whole frames, in bounded memory.

:class:`ExportStream` reads the file in chunks (``BLOCK_BYTES`` of text at a time), so an export of any length is
parsed with memory set by the block size and one frame's size, not by the file's. Only regular files are read (a
device such as ``/dev/zero``, or a link to one, is refused before a byte is read), and a file larger than
``max_bytes`` is refused up front: pass a larger ``max_bytes`` (``--max-bytes`` on the command line) to read it.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.hardware.tekscan.body import FrameBlock, is_frame_line, parse_block
from palpate.hardware.tekscan.header import (
    FRAME_LINE,
    ExportHeader,
    export_header,
    int_entry,
    parse_header,
    split_key,
)

#: Largest export read by default, bytes; raise it with ``max_bytes`` / ``--max-bytes``.
MAX_EXPORT_BYTES = 8 << 30
#: Text parsed per block (the memory a read needs is a few times this).
BLOCK_BYTES = 1 << 20
# A header longer than this, or a line longer than MAX_LINE, is not a Tekscan export.
MAX_HEADER_CHARS = 1 << 20
MAX_LINE = 1 << 20


def regular_file(path, max_bytes: int, what: str) -> int:
    """Size of ``path`` if it is a regular file of at most ``max_bytes``; ValidationError naming it otherwise."""
    path = Path(path)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise ValidationError(f"{path}: cannot read {what}: {exc.strerror}") from None
    if not stat.S_ISREG(st.st_mode):
        raise ValidationError(f"{path}: cannot read {what}: not a regular file (a device, pipe or folder"
                              f"{', reached through a link' if path.is_symlink() else ''})")
    if st.st_size > max_bytes:
        raise ValidationError(f"{path}: {what} is {st.st_size / 1e6:.0f} MB, more than the {max_bytes / 1e6:.0f} MB "
                              "read by default; raise the limit with --max-bytes (max_bytes=) if the file is right")
    return int(st.st_size)


class ExportStream:
    """An export read block by block: ``header`` at once, then :meth:`blocks`.

    Args:
        chunks: the file's text in pieces (line ends may fall anywhere).
        name: the name errors use.
        full_scale_pa: saturation pressure, Pa, for non-RAW exports without SATURATION_PRESSURE.

    After :meth:`blocks` is exhausted, ``frames`` counts the frames read and every check that needs the whole
    file (FRAMES, END_FRAME, at least one frame) has been made.
    """

    def __init__(self, chunks: Iterator[str], name: str, *, full_scale_pa: float | None = None):
        self.name = name
        self._chunks = chunks
        self._rem = ""
        self._next_line = 0  # 0-based file line index of the next line _lines() returns
        self._buffer: list[str] = []
        header_lines = self._header_lines()
        entries, body_start = parse_header(header_lines, name)
        self._buffer = header_lines[body_start:]
        self._body_first = body_start
        self.header: ExportHeader = export_header(entries, name, full_scale_pa)
        self.frames = 0
        self.first_number: int | None = None
        self.last_number: int | None = None

    # ---- lines ---------------------------------------------------------------------------------------------
    def _more_lines(self) -> list[str] | None:
        """The next complete lines (CRLF, LF or CR ends), or None at the end of the text."""
        for text in self._chunks:
            text = self._rem + text
            # a CR at the very end may be the first half of a CR LF: keep it for the next piece
            held = "\r" if text.endswith("\r") else ""
            parts = (text[:-1] if held else text).replace("\r\n", "\n").replace("\r", "\n").split("\n")
            self._rem = parts.pop() + held
            if len(self._rem) > MAX_LINE:
                raise ValidationError(f"{self.name}:{self._next_line + len(parts) + 1}: a line longer than "
                                      f"{MAX_LINE} characters: not a Tekscan ASCII export")
            if parts:
                self._next_line += len(parts)
                return parts
        if self._rem:
            last, self._rem = self._rem.rstrip("\r"), ""
            self._next_line += 1
            return [last]
        return None

    def _header_lines(self) -> list[str]:
        lines: list[str] = []
        size = 0
        while True:
            more = self._more_lines()
            if more is None or size > MAX_HEADER_CHARS:
                return lines  # parse_header says what is missing
            lines += more
            size += sum(len(s) for s in more)
            for s in more:
                s = s.strip().rstrip(",").strip()
                if s and (FRAME_LINE.match(s) or split_key(s)[0] == "ASCII_DATA"):
                    return lines

    # ---- frames --------------------------------------------------------------------------------------------
    def blocks(self) -> Iterator[FrameBlock]:
        """Blocks of whole frames in file order; ValidationError naming file and line for anything wrong."""
        h = self.header
        pending, first = self._buffer, self._body_first
        self._buffer = []
        size = sum(len(s) for s in pending)
        while True:
            more = self._more_lines()
            if more is not None:
                pending += more
                size += sum(len(s) for s in more)
                if size < BLOCK_BYTES:
                    continue
            # frames are complete up to the last Frame line (all of them at the end of the text)
            cut = len(pending)
            if more is not None:
                cut = next((i for i in range(len(pending) - 1, -1, -1) if is_frame_line(pending[i].strip())), 0)
                if cut == 0:
                    continue  # one frame larger than a block: read on
            if self.frames == 0 and not any(s.strip() for s in pending[:cut]):
                if more is None:
                    raise ValidationError(f"{self.name}: no 'Frame N' line after the header (line {first})")
                continue
            if any(s.strip() for s in pending[:cut]):
                block = parse_block(pending[:cut], first, h.rows, h.cols, self.name)
                self._account(block, first)
                yield block
            first += cut
            pending = pending[cut:]
            size = sum(len(s) for s in pending)
            if more is None:
                self._check_totals()
                return

    def _account(self, block: FrameBlock, first: int) -> None:
        n0, n1 = int(block.numbers[0]), int(block.numbers[-1])
        if self.last_number is not None and n0 <= self.last_number:
            raise ValidationError(f"{self.name}:{int(block.line_of_frame[0])}: Frame {n0} follows Frame "
                                  f"{self.last_number}; frame numbers must increase")
        if self.first_number is None:
            self.first_number = n0
            start = self.start_frame
            if n0 < start:
                raise ValidationError(f"{self.name}: first frame is Frame {n0}, before START_FRAME {start} "
                                      f"(line {self.header.entries['START_FRAME'][1]})")
        self.last_number = n1
        self.frames += len(block.numbers)

    @property
    def start_frame(self) -> int:
        """START_FRAME, or the first frame's number."""
        default = self.first_number if self.first_number is not None else 0
        return int_entry(self.header.entries, "START_FRAME", self.name, default=default, minimum=0)

    def times(self, numbers: np.ndarray) -> np.ndarray:
        """Frame times, s, from START_FRAME."""
        return (numbers - self.start_frame).astype(np.float64) * self.header.seconds_per_frame

    def _check_totals(self) -> None:
        entries, name = self.header.entries, self.name
        if "END_FRAME" in entries:
            end = int_entry(entries, "END_FRAME", name, minimum=self.start_frame)
            if self.last_number > end:
                raise ValidationError(f"{name}: last frame is Frame {self.last_number}, after END_FRAME {end} "
                                      f"(line {entries['END_FRAME'][1]})")
        if "FRAMES" in entries:
            expected = int_entry(entries, "FRAMES", name, minimum=1)
            if expected != self.frames:
                raise ValidationError(f"{name}:{entries['FRAMES'][1]}: FRAMES says {expected} frames, the file has "
                                      f"{self.frames}")


def file_chunks(path: Path, chunk_bytes: int | None = None) -> Iterator[str]:
    """A file's text in pieces: UTF-8 after a byte-order mark, else Latin-1 (Tekscan writes Windows-1252/ASCII;
    Latin-1 maps every byte, so a stray byte becomes a parse error on its line)."""
    chunk_bytes = chunk_bytes or BLOCK_BYTES
    with open(path, "rb") as f:
        first = True
        while True:
            raw = f.read(chunk_bytes)
            if not raw:
                return
            if first and raw.startswith(b"\xef\xbb\xbf"):
                # the rest is UTF-8: decode incrementally so a character split between chunks survives
                import codecs

                decoder = codecs.getincrementaldecoder("utf-8")(errors="replace")
                yield decoder.decode(raw[3:])
                while raw := f.read(chunk_bytes):
                    yield decoder.decode(raw)
                yield decoder.decode(b"", final=True)
                return
            first = False
            yield raw.decode("latin-1")


def open_export(path, *, full_scale_pa: float | None = None, max_bytes: int = MAX_EXPORT_BYTES) -> ExportStream:
    """Open a Tekscan export for streaming (regular files of at most ``max_bytes`` only)."""
    path = Path(path)
    regular_file(path, max_bytes, "Tekscan export")
    try:
        return ExportStream(file_chunks(path), path.name, full_scale_pa=full_scale_pa)
    except OSError as exc:
        raise ValidationError(f"{path}: cannot read Tekscan export: {exc.strerror}") from None
