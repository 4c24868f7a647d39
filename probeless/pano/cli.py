"""``probeless pano glossy | diffuse | itmo``: accuracy evaluations of the 360° IBL methods (paper 002)."""

from __future__ import annotations

import argparse
from typing import Any


def add_pano_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``pano`` command group and its evaluations."""
    from probeless.pano.diffuse_eval import add_parser as add_diffuse
    from probeless.pano.glossy_eval import add_parser as add_glossy
    from probeless.pano.itmo_eval import add_parser as add_itmo

    p = subparsers.add_parser("pano", help="360° video IBL (paper 002): accuracy of the fast paths against "
                                           "brute-force references")
    sub = p.add_subparsers(dest="pano_command", required=True)
    add_glossy(sub)
    add_diffuse(sub)
    add_itmo(sub)
    return p
