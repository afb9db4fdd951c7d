"""Polhemus Liberty motion tracker: binary/ASCII protocol driver and a pty emulator."""


def register_cli(groups: dict) -> None:
    """Add ``palpate record liberty`` (see :mod:`palpate.hardware.polhemus.cli`)."""
    from palpate.hardware.polhemus.cli import add_record_command

    add_record_command(groups["record"])
