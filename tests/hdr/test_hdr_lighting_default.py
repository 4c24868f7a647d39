"""Issue 27: giving an HDR photo to launch/probeless.yaml selects the HDR lighting path without further flags
(``lighting: {default: $(given photo hdr ldr)}``); ``$(given NAME THEN ELSE)`` itself."""

from __future__ import annotations

import pytest
from locations import REPO

from probeless.errors import ProbelessError
from probeless.launch.graph import parse_graph
from probeless.launch.launcher import load_checked

GRAPH = REPO / "launch/probeless.yaml"
HDR_NODES = {"photo", "hdr_atlas", "hdr_dense"}


def test_photo_arg_selects_the_hdr_lighting_path(monkeypatch, tmp_path):
    monkeypatch.chdir(REPO)  # the graph's default files are relative to the repository
    photo = tmp_path / "room.hdr"
    photo.write_bytes((REPO / "launch/scenes/photos/convex_room.hdr").read_bytes())
    plain = load_checked(str(GRAPH), {})                          # what `probeless check` loads
    given = load_checked(str(GRAPH), {"photo": str(photo)})
    assert plain.args["lighting"] == "ldr" and not HDR_NODES & set(plain.nodes)
    assert given.args["lighting"] == "hdr" and HDR_NODES <= set(given.nodes)
    assert given.nodes["photo"].params["path"] == str(photo)
    src = {k: v.source for k, v in given.nodes["envmap"].inputs.items()}
    assert src["atlas"] == "hdr_atlas/atlas" and src["hdr_points"] == "hdr_dense/cloud"
    # an explicit lighting:= still wins, both ways
    assert not HDR_NODES & set(load_checked(str(GRAPH), {"photo": str(photo), "lighting": "ldr"}).nodes)
    assert HDR_NODES <= set(load_checked(str(GRAPH), {"lighting": "hdr"}).nodes)


def _graph(tmp_path, text: str):
    path = tmp_path / "g.yaml"
    path.write_text(text)
    return path


def test_given_substitution_in_defaults_and_body(tmp_path):
    path = _graph(tmp_path, """args:
  a: {default: x}
  b: {default: $(given a yes no)}
nodes:
  - id: n
    node: summary_sink
    params: {out_dir: $(given a on off)}
""")
    for overrides, want_b, want_label in (({}, "no", "off"), ({"a": "x"}, "yes", "on"), ({"b": "z"}, "z", "off")):
        g = parse_graph(path, overrides)
        assert g.args["b"] == want_b and g.nodes["n"].params["out_dir"] == want_label


@pytest.mark.parametrize("use, message", [("$(given a yes)", "two words"), ("$(given nope yes no)", "undeclared")])
def test_given_substitution_errors_name_the_file_and_line(tmp_path, use, message):
    path = _graph(tmp_path, f"args:\n  a: {{default: x}}\nnodes:\n  - id: n\n    node: summary_sink\n"
                            f"    params: {{out_dir: '{use}'}}\n")
    with pytest.raises(ProbelessError) as exc:
        load_checked(str(path), {})
    text = str(exc.value)
    assert message in text and "g.yaml" in text and ":6" in text
