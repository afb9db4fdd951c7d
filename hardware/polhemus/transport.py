"""Byte transports to a Liberty: RS-232 (or a pseudo-terminal) through pyserial, USB bulk through pyusb.

A transport moves bytes and nothing else; the driver does not know which one it has (nor whether an emulator is
at the other end). Both libraries are imported only when a transport is opened.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from palpate.core.errors import DeviceError, ValidationError
from palpate.hardware.clock import read_arrived

# USB identity of a Liberty (v2): vendor Polhemus 0x0F44, product 0xFF20; bulk endpoints IN 0x88, OUT 0x04.
LIBERTY_USB_VENDOR = 0x0F44
LIBERTY_USB_PRODUCT = 0xFF20
LIBERTY_EP_IN = 0x88
LIBERTY_EP_OUT = 0x04
LIBERTY_BAUDS = (2400, 4800, 9600, 19200, 38400, 57600, 115200)


@runtime_checkable
class Transport(Protocol):
    """What the driver needs from a link: bytes in, bytes out."""

    description: str

    def read(self, n: int) -> bytes:  # pragma: no cover - protocol
        """Return up to n bytes; fewer (possibly none) after the read timeout."""
        ...

    def write(self, data: bytes) -> None:  # pragma: no cover - protocol
        """Send all of data."""
        ...

    def reset_input(self) -> None:  # pragma: no cover - protocol
        """Discard bytes received and not yet read."""
        ...

    def close(self) -> None:  # pragma: no cover - protocol
        ...


class SerialTransport:
    """A serial port (RS-232, USB-serial adapter or pseudo-terminal) opened with pyserial.

    Args:
        port: device path, e.g. /dev/ttyUSB0 or the slave path of a pty.
        baudrate: the Liberty's baud rate (set on the device; the host must match it).
        timeout: read timeout, s: ``read`` returns what arrived within it.
    """

    def __init__(self, port: str, baudrate: int = 115200, timeout: float = 0.05):
        if int(baudrate) not in LIBERTY_BAUDS:
            raise ValidationError(
                f"baud rate {baudrate} is not one a Liberty supports; expected one of {LIBERTY_BAUDS}"
            )
        if not timeout > 0:
            raise ValidationError(f"serial read timeout must be > 0 s, got {timeout}")
        try:
            import serial
        except ImportError as exc:
            raise DeviceError(
                "pyserial is needed for the Liberty serial link: pip install 'palpate[hardware]'"
            ) from exc
        self.port = str(port)
        self.baudrate = int(baudrate)
        self.description = f"{self.port} at {self.baudrate} baud"
        try:
            self._serial = serial.Serial(self.port, self.baudrate, timeout=timeout, write_timeout=1.0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise DeviceError(
                f"cannot open serial port {self.port!r}: {exc}. Check the port name and permissions."
            ) from exc

    def read(self, n: int) -> bytes:
        try:
            return read_arrived(self._serial, n)
        except Exception as exc:  # pyserial raises SerialException or OSError when the port goes away
            raise DeviceError(f"reading from {self.description} failed: {exc}") from exc

    def write(self, data: bytes) -> None:
        try:
            self._serial.write(data)
            self._serial.flush()
        except Exception as exc:
            raise DeviceError(f"writing to {self.description} failed: {exc}") from exc

    def reset_input(self) -> None:
        self._serial.reset_input_buffer()

    def close(self) -> None:
        self._serial.close()

    def __enter__(self) -> SerialTransport:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class UsbTransport:
    """A Liberty on USB, read and written through bulk endpoints with pyusb (optional dependency).

    Args:
        vendor, product: USB ids (default: Polhemus Liberty v2).
        timeout: read timeout, s.
    """

    def __init__(self, vendor: int = LIBERTY_USB_VENDOR, product: int = LIBERTY_USB_PRODUCT, timeout: float = 0.05):
        try:
            import usb.core
        except ImportError as exc:
            raise DeviceError(
                "the USB link needs pyusb (pip install pyusb) and libusb; or use the RS-232 port with --port"
            ) from exc
        self.description = f"USB {vendor:04x}:{product:04x}"
        self._usb = usb.core
        self._timeout_ms = max(1, int(timeout * 1000))
        dev = usb.core.find(idVendor=vendor, idProduct=product)
        if dev is None:
            raise DeviceError(f"no USB device {vendor:04x}:{product:04x} found; is the Liberty on and plugged in?")
        try:
            dev.set_configuration()
        except usb.core.USBError as exc:
            raise DeviceError(f"cannot configure {self.description}: {exc} (permissions on /dev/bus/usb?)") from exc
        self._dev = dev
        self._buffer = b""

    def read(self, n: int) -> bytes:
        if len(self._buffer) < n:
            try:
                self._buffer += bytes(self._dev.read(LIBERTY_EP_IN, 512, timeout=self._timeout_ms))
            except self._usb.USBTimeoutError:
                pass
            except self._usb.USBError as exc:
                raise DeviceError(f"reading from {self.description} failed: {exc}") from exc
        out, self._buffer = self._buffer[:n], self._buffer[n:]
        return out

    def write(self, data: bytes) -> None:
        try:
            self._dev.write(LIBERTY_EP_OUT, data, timeout=1000)
        except self._usb.USBError as exc:
            raise DeviceError(f"writing to {self.description} failed: {exc}") from exc

    def reset_input(self) -> None:
        # Bounded: a streaming device never runs dry, and this only needs to drop what is already queued.
        for _ in range(64):
            self._buffer = b""
            if not self.read(512):
                break
        self._buffer = b""

    def close(self) -> None:
        import usb.util

        usb.util.dispose_resources(self._dev)

    def __enter__(self) -> UsbTransport:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
