"""``python -m wbc ...``: the ``wbc`` command (:func:`wbc.app.cli.console`)."""

from .app.cli import console

console()
