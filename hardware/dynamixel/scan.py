"""Find the servos on a Dynamixel bus (``palpate devices scan dynamixel``)."""

from __future__ import annotations

from collections.abc import Iterable

from palpate.core.errors import DeviceError, ValidationError
from palpate.hardware.dynamixel import control_table as ct
from palpate.hardware.dynamixel.driver import SERIAL_POLL


def scan(port: str, baud: int, ids: Iterable[int] = range(0, 253), timeout_ms: float | None = None) -> list[dict]:
    """Ping ``ids`` on ``port``; returns ``[{"id", "model_number", "model", "firmware"}]`` for each that answers."""
    import dynamixel_sdk as sdk

    ph = sdk.PacketHandler(2.0)
    p = sdk.PortHandler(str(port))
    try:
        opened = p.openPort()
    except Exception as exc:
        raise DeviceError(f"cannot open Dynamixel port {port!r}: {exc}") from None
    if not opened:
        raise DeviceError(f"cannot open Dynamixel port {port!r}")
    try:
        if not p.setBaudRate(int(baud)):
            raise DeviceError(f"baud {baud} is not supported by dynamixel-sdk")
        p.ser.timeout = SERIAL_POLL  # reads that wait, not a busy loop (see driver.SERIAL_POLL)
        if timeout_ms is not None:  # e.g. an emulator sharing a loaded machine: wait longer for each answer
            p.setPacketTimeout = lambda _length: p.setPacketTimeoutMillis(float(timeout_ms))
        found = []
        for sid in ids:
            if not 0 <= sid <= 252:
                raise ValidationError(f"servo ids are 0..252, got {sid}")
            number, result, _ = ph.ping(p, sid)
            if result in (sdk.COMM_RX_CORRUPT, sdk.COMM_RX_TIMEOUT):
                # one retry: a single corrupt or missed answer is not an absent servo
                number, result, _ = ph.ping(p, sid)
            if result == sdk.COMM_SUCCESS:
                fw, r2, _ = ph.read1ByteTxRx(p, sid, ct.FIRMWARE_VERSION[0])
                found.append({"id": sid, "model_number": int(number), "model": ct.model_name(int(number)),
                              "firmware": int(fw) if r2 == sdk.COMM_SUCCESS else None})
        return found
    finally:
        p.closePort()

