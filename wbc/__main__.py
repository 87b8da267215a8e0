"""``python -m wbc ...``: the ``wbc`` command (:func:`wbc.app.cli.main`)."""

import sys

from .app.cli import main

sys.exit(main())
