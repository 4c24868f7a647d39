"""Compatibility module: the topic tools now live in the :mod:`probeless.topics` package.

``from probeless.topic_tools import ...`` and ``python -m probeless.topic_tools`` keep working.
"""

from __future__ import annotations

import sys

from probeless.topics import *  # noqa: F401,F403
from probeless.topics import __all__  # noqa: F401
from probeless.topics.cli import topic_main

if __name__ == "__main__":
    sys.exit(topic_main())
