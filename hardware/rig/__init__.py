"""A rig of several devices used together: a tactile pad and a pose tracker on one fingertip.

- ``palpate import session``: a Tekscan export and a Liberty recording of the same presses, made on two
  computers, merged into one recording on the pad's clock and in the workspace grid's frame
  (:mod:`palpate.hardware.rig.session_import`; the clock and workspace alignment is
  :mod:`palpate.core.alignment`);
- ``palpate record session``: a live tactile array and a Liberty recorded into one file on one host clock
  (:mod:`palpate.hardware.rig.session_record`).
"""


def register_cli(groups: dict) -> None:
    """Add ``palpate import session`` and ``palpate record session`` (see :mod:`palpate.hardware.cli`)."""
    from palpate.hardware.rig.session_import import add_import_command
    from palpate.hardware.rig.session_record import add_record_command

    add_import_command(groups["import"])
    add_record_command(groups["record"])
