"""``python -m probeless.topics list``: the ``probeless topic`` tools on their own."""

import sys

from probeless.topics.cli import topic_main

sys.exit(topic_main())
