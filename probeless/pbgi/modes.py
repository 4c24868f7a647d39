"""The relighting modes of :class:`~probeless.pbgi.relight.Relighter` (described there).

Kept apart from :mod:`~probeless.pbgi.relight` so the command line can offer them without importing the
renderer (numba kernels, GL): every ``probeless`` command builds that parser."""

MODES = ("full", "near_field", "envmap")
