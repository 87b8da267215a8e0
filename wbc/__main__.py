"""``python -m wbc ...``: the ``wbc`` command (:func:`wbc.cli.main`)."""

import sys

from .cli import main

sys.exit(main())
