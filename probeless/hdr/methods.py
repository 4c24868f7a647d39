"""The names of the HDR expansion methods and the default view count (see :mod:`probeless.hdr.expand`).

Kept apart from :mod:`~probeless.hdr.expand` so the command line can offer them without importing the
expansion itself (scipy, the splat renderer): every ``probeless`` command builds that parser."""

METHODS = ("landis", "banterle", "landis-pc", "banterle-pc", "pmatch-lum", "pmatch-rgb")
DEFAULT_VIEWS = 3
