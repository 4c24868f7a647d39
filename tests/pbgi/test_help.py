"""``probeless pbgi render --help`` lists every material type of the scene format with its keys and the roughness
convention (the reference: the material registry of probeless.ibl.materials, which parses --material)."""

from __future__ import annotations

import re
from dataclasses import fields

import pytest

from probeless.cli import main
from probeless.ibl import materials


def test_help_lists_every_material_type_its_keys_and_alpha(capsys):
    with pytest.raises(SystemExit) as done:
        main(["pbgi", "render", "--help"])
    assert done.value.code == 0
    text = capsys.readouterr().out
    assert "alpha = roughness^2" in text
    for name, cls in materials._TYPES.items():
        line = next((ln for ln in text.splitlines() if re.match(rf"\s+{name}\b", ln)), None)
        assert line is not None, f"material type {name!r} missing from --help"
        if name in ("glass",):
            assert "not rendered" in line
            continue
        for f in fields(cls):
            assert re.search(rf"\b{f.name}\b", line), f"{name}: key {f.name!r} missing from --help"
    assert re.search(r"^\s+metal\s+colour \[", text, re.M)  # the case: metal with colour
