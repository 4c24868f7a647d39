"""``python -m probeless``: the ``probeless`` command (:func:`probeless.cli.main`)."""

import sys

from probeless.cli import main

sys.exit(main())
