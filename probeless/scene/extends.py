"""Scene inheritance: a top-level ``extends: base.yaml`` (relative to the file) deep-merges the file onto its base.

Mappings merge key by key (the extending file wins), lists and scalars replace. Bases may extend further
bases; a cycle is an error. A relative file path (texture, mesh, ``from_file``) is relative to the file
that writes it: a base's are made absolute before merging, so the merged document loads from anywhere.
"""

from __future__ import annotations

from pathlib import Path

from probeless.errors import GraphError, SceneError
from probeless.launch.yamlload import LineDict, load_yaml


def deep_merge(base, over):
    """``over`` merged onto ``base``: mappings key by key (recursively), anything else replaced by ``over``."""
    if not (isinstance(base, dict) and isinstance(over, dict)):
        return over
    out = LineDict(base)
    out.line = getattr(over, "line", getattr(base, "line", 0))
    out.lines = {**getattr(base, "lines", {}), **getattr(over, "lines", {})}
    for key, value in over.items():
        out[key] = deep_merge(base[key], value) if key in base else value
    return out


def load_scene_doc(path: Path, _seen: tuple[Path, ...] = ()) -> tuple[dict, list[Path]]:
    """The scene document at ``path`` with its ``extends`` chain merged, and the chain of base files (nearest first)."""
    try:
        doc = load_yaml(path)
    except GraphError as exc:
        raise SceneError(exc.format()) from None
    if not isinstance(doc, dict) or "extends" not in doc:
        return doc, []
    ref = doc["extends"]
    if not isinstance(ref, str) or not ref:
        raise SceneError(f"{path}:{doc.line_of('extends')}: extends: expected a file name, got {ref!r}")
    base_path = (path.parent / ref).resolve()
    if base_path in _seen or base_path == path.resolve():
        raise SceneError(f"{path}:{doc.line_of('extends')}: extends: {ref} forms a cycle")
    if not base_path.is_file():
        raise SceneError(f"{path}:{doc.line_of('extends')}: extends: file not found: {base_path}")
    base, chain = load_scene_doc(base_path, _seen + (path.resolve(),))
    if not isinstance(base, dict):
        raise SceneError(f"{base_path}: expected a mapping at the top (extended by {path})")
    _absolute_paths(base, base_path.parent)
    over = LineDict({k: v for k, v in doc.items() if k != "extends"})
    over.line, over.lines = doc.line, {k: n for k, n in doc.lines.items() if k != "extends"}
    return deep_merge(base, over), [base_path, *chain]


def _absolute_paths(doc: dict, folder: Path) -> None:
    """Make the relative file paths a scene document names absolute against ``folder`` (in place)."""
    def fix(container, key):
        if isinstance(container, dict) and isinstance(container.get(key), str) and container[key]:
            container[key] = str(folder / container[key])  # an absolute path stays as it is

    def get(container, key):
        return container.get(key) if isinstance(container, dict) else None

    materials = get(get(doc, "room"), "materials")
    for name in ("walls", "floor", "ceiling"):
        fix(get(materials, name), "texture")
    furniture = doc.get("furniture")
    for item in furniture if isinstance(furniture, list) else ():
        fix(get(item, "mesh"), "path")
    for key in ("extrinsics", "fisheye_intrinsics"):
        fix(get(get(doc, "given"), key), "from_file")


def plain(value):
    """``value`` with the YAML line-tracking containers turned into plain dicts and lists (for yaml.safe_dump)."""
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [plain(v) for v in value]
    return value


def scene_yaml(path: str | Path) -> str:
    """The text that re-loads the scene at ``path``: the file itself, or with ``extends`` the merged document."""
    import yaml

    path = Path(path)
    doc, chain = load_scene_doc(path)
    if not chain:
        return path.read_text()
    header = f"# {path.name} merged with {', '.join(p.name for p in chain)} (extends resolved)\n"
    return header + yaml.safe_dump(plain(doc), sort_keys=False, default_flow_style=None)
