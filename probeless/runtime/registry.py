"""Node types by name: what a graph's ``node:`` names, resolved to a Node class.

A ``node:`` entry is one of

* a registered name: a built-in (``probeless.nodes.BUILTIN``) or a name another installed package
  registers in the ``probeless.nodes`` entry-point group (``[project.entry-points."probeless.nodes"]``
  ``blur = "my_nodes.blur:Blur"`` in its pyproject.toml; see examples/my_nodes/);
* ``path/to/file.py:Class``: a Python file, relative to the graph file's folder (``base``) unless
  absolute; its folder is added to the import path so it can import its neighbours;
* ``module:Class``: a module on the import path, or else found in the graph file's folder.

An import or syntax error in a node's module is a GraphError of one line naming the file and line.
"""

from __future__ import annotations

import difflib
import importlib
import importlib.util
import sys
import traceback
import zlib
from functools import lru_cache
from importlib.metadata import entry_points
from pathlib import Path
from types import ModuleType

from probeless.errors import GraphError

ENTRY_POINT_GROUP = "probeless.nodes"


@lru_cache(maxsize=1)
def node_types() -> dict[str, str]:
    """All registered node type names mapped to ``module:Class`` (built-ins win over entry points)."""
    from probeless.nodes import BUILTIN

    names = dict(BUILTIN)
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        names.setdefault(ep.name, ep.value)
    return names


def builtin_names() -> set[str]:
    """The names of the node types this package ships."""
    from probeless.nodes import BUILTIN

    return set(BUILTIN)


def is_file_target(module_part: str) -> bool:
    """True when the part before ``:`` names a Python file rather than a module."""
    return module_part.endswith(".py") or "/" in module_part or "\\" in module_part


def resolve_node(name: str, base: str | Path | None = None) -> type:
    """The node class for a ``node:`` entry; GraphError (one line) when it cannot be had.

    ``base`` is the folder of the graph file that names it: ``file.py:Class`` is taken relative to
    it, and ``module:Class`` is looked for there when the import path does not have it.
    """
    from probeless.runtime.node import Node

    target = node_types().get(name, name)
    if ":" not in target:
        close = difflib.get_close_matches(name, node_types(), n=3)
        hint = f" (did you mean {', '.join(close)}?)" if close else ""
        raise GraphError(f"unknown node type {name!r}{hint}; use a registered name (`probeless nodes list`), "
                         "module:Class or path/to/file.py:Class", key="node")
    module_part, _, attr = target.rpartition(":")
    if not module_part or not attr:
        raise GraphError(f"node type {name!r}: expected module:Class or path/to/file.py:Class", key="node")
    if is_file_target(module_part):
        module = _load_file(name, module_part, base)
    else:
        module = _import_module(name, module_part, base)
    cls = getattr(module, attr, None)
    where = getattr(module, "__file__", None) or module_part
    if cls is None:
        raise GraphError(f"node type {name!r}: {where} has no class {attr!r}", key="node")
    if not (isinstance(cls, type) and issubclass(cls, Node)):
        raise GraphError(f"node type {name!r}: {attr} in {where} is not a subclass of probeless.runtime.Node",
                         key="node")
    return cls


_FILE_MODULES: dict[Path, ModuleType] = {}


def _load_file(name: str, module_part: str, base: str | Path | None) -> ModuleType:
    path = Path(module_part).expanduser()
    if not path.is_absolute():
        path = Path(base or ".") / path
    path = path.resolve()
    if path in _FILE_MODULES:
        return _FILE_MODULES[path]
    if not path.is_file():
        rel = "" if Path(module_part).is_absolute() else \
            f" (relative to the graph's folder {Path(base).resolve()})" if base else " (relative to the working folder)"
        raise GraphError(f"node type {name!r}: no file {path}{rel}", key="node")
    folder = str(path.parent)
    if folder not in sys.path:
        sys.path.append(folder)  # the node's own helper modules beside it import as in a script
    mod_name = f"probeless_user_nodes.{path.stem}_{zlib.crc32(str(path).encode()):08x}"
    spec = importlib.util.spec_from_file_location(mod_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module  # dataclasses and type hints look the module up by name
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - any error in the user's module becomes one line
        sys.modules.pop(mod_name, None)
        raise GraphError(f"node type {name!r}: {_one_line(exc)}", key="node") from None
    _FILE_MODULES[path] = module
    return module


def _import_module(name: str, module_name: str, base: str | Path | None) -> ModuleType:
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        top = module_name.split(".")[0]
        if exc.name not in (top, module_name) and not module_name.startswith(f"{exc.name}."):
            raise GraphError(f"node type {name!r}: {_one_line(exc)}", key="node") from None
        folder = Path(base).resolve() if base else None
        if folder is None or not ((folder / f"{top}.py").is_file() or (folder / top).is_dir()):
            where = f" nor in the graph's folder {folder}" if folder else ""
            raise GraphError(f"node type {name!r}: no module {module_name!r} on the import path{where} "
                             f"(a file beside the graph can be named as path/to/file.py:Class)",
                             key="node") from None
    except Exception as exc:  # noqa: BLE001 - syntax or import error inside the module: one line
        raise GraphError(f"node type {name!r}: {_one_line(exc)}", key="node") from None
    if str(folder) not in sys.path:
        sys.path.append(str(folder))  # after the import path: installed modules win
    importlib.invalidate_caches()
    try:
        return importlib.import_module(module_name)
    except Exception as exc:  # noqa: BLE001
        raise GraphError(f"node type {name!r}: {_one_line(exc)}", key="node") from None


def _one_line(exc: BaseException) -> str:
    """``file:line: Type: message`` of an error raised while importing a module (no traceback)."""
    if isinstance(exc, SyntaxError) and exc.filename:
        return f"{exc.filename}:{exc.lineno}: {type(exc).__name__}: {exc.msg}"
    frames = [f for f in traceback.extract_tb(exc.__traceback__) if "importlib" not in f.filename
              and not f.filename.startswith("<frozen")]
    where = f"{frames[-1].filename}:{frames[-1].lineno}: " if frames else ""
    text = str(exc).splitlines()[0] if str(exc) else ""
    return f"{where}{type(exc).__name__}: {text}" if text else f"{where}{type(exc).__name__}"
