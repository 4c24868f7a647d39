"""Recording and reading bus traffic as MCAP files (``probeless bag``).

A recording stores each message exactly as it crossed the wire (see :mod:`probeless.bag.format`),
so replay is bit-exact and decoding uses the ordinary schema checks.
"""

from probeless.bag.reader import BagMessage, BagReader, TopicInfo
from probeless.bag.writer import BagWriter, recording_paths, split_paths

__all__ = ["BagMessage", "BagReader", "BagWriter", "TopicInfo", "recording_paths", "split_paths"]
