"""Safe YAML loading that remembers the line of every mapping key, for error messages.

Hostile input is refused early with a GraphError naming the file (and line): a file larger than
:data:`MAX_YAML_BYTES`, nesting deeper than :data:`MAX_DEPTH`, or aliases whose expansion would
exceed :data:`MAX_NODES` nodes ("billion laughs"). Each check costs time linear in the file size.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from probeless.errors import GraphError

MAX_YAML_BYTES = 8 * 1024 * 1024   # graphs, scenes and params files are kilobytes
MAX_DEPTH = 64                     # nesting of mappings and sequences
MAX_NODES = 1_000_000              # scalars + collections with every alias expanded


class LineDict(dict):
    """A dict from YAML with ``line`` (of the mapping) and ``lines`` (of each key), 1-based."""

    line: int = 0
    lines: dict

    def line_of(self, key: str) -> int:
        return self.lines.get(key, self.line)


class LineList(list):
    """A list from YAML with the line of the sequence and of each item."""

    line: int = 0
    lines: list


class _Loader(yaml.SafeLoader):
    """SafeLoader with line-keeping containers and the depth / alias-expansion limits."""

    def __init__(self, stream):
        super().__init__(stream)
        self.depth = 0
        self.sizes: dict[int, int] = {}   # id(node) -> node count with aliases expanded

    def fetch_flow_collection_start(self, token_class):
        # the scanner looks ahead over nested flow brackets in quadratic time: stop it early
        if self.flow_level >= MAX_DEPTH:
            raise GraphError(f"YAML nested deeper than {MAX_DEPTH} levels", file=self.name,
                             line=self.get_mark().line + 1)
        super().fetch_flow_collection_start(token_class)

    def compose_node(self, parent, index):
        self.depth += 1
        try:
            if self.depth > MAX_DEPTH:
                raise GraphError(f"YAML nested deeper than {MAX_DEPTH} levels", file=self.name,
                                 line=self.peek_event().start_mark.line + 1)
            node = super().compose_node(parent, index)
        finally:
            self.depth -= 1
        self._count(node)
        return node

    def _count(self, node: yaml.Node) -> None:
        if id(node) in self.sizes:
            return
        children = node.value if isinstance(node, yaml.SequenceNode) else (
            [n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode) else [])
        size = 1 + sum(self.sizes.get(id(c), 1) for c in children)
        if size > MAX_NODES:
            raise GraphError(f"YAML aliases expand to more than {MAX_NODES} nodes (an alias bomb?)",
                             file=self.name, line=node.start_mark.line + 1)
        self.sizes[id(node)] = size


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> LineDict:
    own = sum(1 for key_node, _ in node.value if key_node.tag != "tag:yaml.org,2002:merge")
    loader.flatten_mapping(node)  # puts the pairs of merge keys (<<: *base) first: the own ones override them
    merged = len(node.value) - own
    out = LineDict()
    out.line = node.start_mark.line + 1
    out.lines = {}
    seen = set()
    for i, (key_node, value_node) in enumerate(node.value):
        key = loader.construct_object(key_node, deep=True)
        if not isinstance(key, (str, int, float, bool)):
            raise GraphError(f"mapping key must be a scalar, got {type(key).__name__}",
                             file=loader.name, line=key_node.start_mark.line + 1)
        if i >= merged and key in seen:
            raise GraphError(f"duplicate key {key!r}", file=loader.name,
                             line=key_node.start_mark.line + 1, key=str(key))
        if i >= merged:
            seen.add(key)
        out[key] = loader.construct_object(value_node, deep=True)
        out.lines[key] = key_node.start_mark.line + 1
    return out


def _construct_sequence(loader: _Loader, node: yaml.SequenceNode) -> LineList:
    out = LineList(loader.construct_object(child, deep=True) for child in node.value)
    out.line = node.start_mark.line + 1
    out.lines = [child.start_mark.line + 1 for child in node.value]
    return out


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


def load_yaml(path: str | Path) -> Any:
    """Parse a YAML file with the safe loader; GraphError naming the file and line on any problem."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            data = f.read(MAX_YAML_BYTES + 1)
    except OSError as exc:
        raise GraphError(f"cannot read: {exc.strerror}", file=str(path)) from None
    if len(data) > MAX_YAML_BYTES:
        raise GraphError(f"file larger than the limit of {MAX_YAML_BYTES} bytes for YAML", file=str(path))
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise GraphError(f"not UTF-8 text (byte {exc.start})", file=str(path)) from None
    return load_yaml_text(text, str(path))


def load_yaml_text(text: str, name: str = "<string>") -> Any:
    """Parse YAML text (``name`` for messages) with the limits of :func:`load_yaml`."""
    if len(text) > MAX_YAML_BYTES:
        raise GraphError(f"text larger than the limit of {MAX_YAML_BYTES} characters for YAML", file=name)
    loader = _Loader(text)
    loader.name = name
    try:
        return loader.get_single_data()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        raise GraphError(f"invalid YAML: {exc.problem or exc.context}", file=name,
                         line=mark.line + 1 if mark else None) from None
    except yaml.YAMLError as exc:
        raise GraphError(f"invalid YAML: {exc}", file=name) from None
    finally:
        loader.dispose()
