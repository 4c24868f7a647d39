"""Node types by name: built-ins from ``probeless.nodes.BUILTIN``, the ``probeless.nodes``
entry-point group of installed packages, or an explicit ``module:Class``."""

from __future__ import annotations

import difflib
import importlib
from functools import lru_cache
from importlib.metadata import entry_points

from probeless.errors import GraphError


@lru_cache(maxsize=1)
def node_types() -> dict[str, str]:
    """All registered node type names mapped to ``module:Class``."""
    from probeless.nodes import BUILTIN

    names = dict(BUILTIN)
    for ep in entry_points(group="probeless.nodes"):
        names.setdefault(ep.name, ep.value)
    return names


def resolve_node(name: str) -> type:
    """The node class for a registered name or ``module:Class``; GraphError when unknown."""
    from probeless.runtime.node import Node

    target = node_types().get(name, name)
    if ":" not in target:
        close = difflib.get_close_matches(name, node_types(), n=3)
        hint = f" (did you mean {', '.join(close)}?)" if close else ""
        raise GraphError(f"unknown node type {name!r}{hint}; use a registered name or module:Class", key="node")
    module_name, _, attr = target.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise GraphError(f"node type {name!r}: cannot import module {module_name!r}: {exc}", key="node") from None
    cls = getattr(module, attr, None)
    if cls is None:
        raise GraphError(f"node type {name!r}: module {module_name!r} has no class {attr!r}", key="node")
    if not (isinstance(cls, type) and issubclass(cls, Node)):
        raise GraphError(f"node type {name!r}: {target} is not a Node subclass", key="node")
    return cls
