"""A rig of several devices used together: a tactile pad and a pose tracker on one fingertip.

- ``palpate import session``: a Tekscan export and a Liberty recording of the same presses, made on two
  computers, merged into one recording on the pad's clock and in the workspace grid's frame
  (:mod:`palpate.hardware.rig.session_import`; the clock and workspace alignment is
  :mod:`palpate.core.alignment`).
"""


def register_cli(groups: dict) -> None:
    """Add ``palpate import session`` (see :mod:`palpate.hardware.cli`)."""
    from palpate.hardware.rig.session_import import add_import_command

    add_import_command(groups["import"])
