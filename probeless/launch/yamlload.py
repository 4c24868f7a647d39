"""Safe YAML loading that remembers the line of every mapping key, for error messages."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from probeless.errors import GraphError


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
    pass


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> LineDict:
    loader.flatten_mapping(node)
    out = LineDict()
    out.line = node.start_mark.line + 1
    out.lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        if not isinstance(key, (str, int, float, bool)):
            raise GraphError(f"mapping key must be a scalar, got {type(key).__name__}",
                             file=loader.name, line=key_node.start_mark.line + 1)
        if key in out:
            raise GraphError(f"duplicate key {key!r}", file=loader.name,
                             line=key_node.start_mark.line + 1, key=str(key))
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
        text = path.read_text()
    except OSError as exc:
        raise GraphError(f"cannot read: {exc.strerror}", file=str(path)) from None
    return load_yaml_text(text, str(path))


def load_yaml_text(text: str, name: str = "<string>") -> Any:
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
