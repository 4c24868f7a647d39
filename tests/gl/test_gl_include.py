"""``#include`` in shader files: resolution order, line numbers kept, errors naming the file and line."""

from __future__ import annotations

import re

import pytest

from probeless.errors import DeviceError
from probeless.gl.context import create_context
from probeless.gl.programs import INCLUDE_DIR, expand_includes, load_program


def test_an_include_is_replaced_by_the_file_and_line_numbers_resume(tmp_path):
    (tmp_path / "local.glsl").write_text("float local_one() { return 1.0; }\n")
    body = 'uniform float a;\n#include "local.glsl"\n#include "fresnel.glsl"\nvoid main() {}\n'
    out = expand_includes(body, tmp_path / "x.frag.glsl", tmp_path, first_line=2).splitlines()
    assert out[0] == "uniform float a;" and out[1] == "float local_one() { return 1.0; }"
    assert out[2] == "#line 4"  # the line after the first include is line 4 of the file (body starts at 2)
    fresnel = (INCLUDE_DIR / "fresnel.glsl").read_text().rstrip("\n").splitlines()
    assert out[3:3 + len(fresnel)] == fresnel and out[3 + len(fresnel)] == "#line 5"
    assert out[-1] == "void main() {}"


def test_a_missing_or_nested_include_names_the_file_and_line(tmp_path):
    with pytest.raises(DeviceError, match=r"x\.frag\.glsl:3: #include \"nope\.glsl\""):
        expand_includes('a\n#include "nope.glsl"\n', tmp_path / "x.frag.glsl", tmp_path, first_line=2)
    (tmp_path / "outer.glsl").write_text('#include "fresnel.glsl"\n')
    with pytest.raises(DeviceError, match="an included file cannot #include"):
        expand_includes('#include "outer.glsl"\n', tmp_path / "x.frag.glsl", tmp_path)


@pytest.mark.gl
@pytest.mark.graph
def test_compiler_messages_keep_the_including_files_line_numbers(tmp_path):
    (tmp_path / "p.vert.glsl").write_text("#version 430\nvoid main() { gl_Position = vec4(0.0); }\n")
    (tmp_path / "p.frag.glsl").write_text(
        '#version 430\n#include "fresnel.glsl"\nout vec4 c;\nvoid main() { c = vec4(fresnel(1.0, 1.5)); }\n'
        "void broken() { undefined_name = 1.0; }\n")  # line 5 of the file
    ctx = create_context()
    try:
        with pytest.raises(DeviceError) as err:
            load_program(ctx, "p", shader_dir=tmp_path)
        assert re.search(r"\b0:5\(", str(err.value)), str(err.value)
        (tmp_path / "p.frag.glsl").write_text(
            '#version 430\n#include "fresnel.glsl"\nout vec4 c;\nvoid main() { c = vec4(fresnel(1.0, 1.5)); }\n')
        load_program(ctx, "p", shader_dir=tmp_path).release()
    finally:
        ctx.release()
