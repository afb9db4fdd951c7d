"""Tekscan tactile arrays: import of the ASCII/CSV movie export (the live API is Windows-only).

- :mod:`palpate.hardware.tekscan.reader`: :func:`read_tekscan` parses an export (format, unit conversions and error
  messages are documented there), :func:`select_region` cuts the 4x4 fingertip pad out of a larger map.
- :mod:`palpate.hardware.tekscan.importer`: :func:`import_tekscan` writes an MCAP recording
  (``palpate import tekscan FILE --out REC.mcap [--region R0:R1,C0:C1] [--start-time ISO8601] [--sensor-id ID]``).

Live frames: a Windows bridge (not part of palpate)
---------------------------------------------------
Tekscan's live acquisition API runs only on Windows, next to Tekscan's own software, so palpate does not talk to the
sensor handle itself and does not pretend to. A bridge is a small program on that Windows machine which takes each
frame from the vendor API as soon as it is acquired and feeds it to palpate in one of two documented ways:

1. **Write the recording directly** (preferred; no network): run Python on Windows and call
   ``palpate.core.io.mcap_writer.RecordingWriter(path, {"sources": [...]})`` then ``write_taxel(TaxelFrame(t, counts,
   sensel_area, sensor_id))`` per frame. ``t`` in s from the bridge's clock; ``counts`` the raw 8-bit frame (RAW
   units, never calibrated pressure); ``sensel_area`` in m^2. The file is the same MCAP an import produces
   (data on ``/palpate/taxels/<sensor_id>``, the image on ``/taxels/<sensor_id>``), crash-safe up to its last
   chunk, and replays with ``palpate replay``.
2. **Stream JSON lines over TCP** to the machine running palpate: UTF-8, one JSON object per ``\\n``-terminated
   line. The first line is ``{"type": "hello", "format": "palpate-taxels-jsonl", "version": 1, "sensor_id": ...,
   "rows": R, "cols": C, "sensel_area": m^2, "clock": "unix" | "monotonic"}``; each following line is one frame with
   exactly the fields of the ``palpate.TaxelFrame`` message schema in :mod:`palpate.core.io.mcap_schemas`
   (``{"t": s, "sensor_id": ..., "rows": R, "cols": C, "sensel_area": m^2, "counts": [R*C ints 0..255, row-major]}``).
   A receiver validates each line exactly as :func:`palpate.core.io.mcap_reader.read_recording` validates a message and
   writes it with ``RecordingWriter.write_taxel``. No receiver ships yet: this is the contract a bridge must meet.
"""

from __future__ import annotations


def register_cli(groups: dict) -> None:
    """Add ``palpate import tekscan`` to the shared command groups (see :mod:`palpate.hardware.cli`)."""
    from palpate.hardware.tekscan.importer import add_import_command

    add_import_command(groups["import"])
