"""The GL device choice of probeless.gl.context: a hardware EGL device when there is one, else the software one."""

from __future__ import annotations

import pytest

from probeless.errors import DeviceError
from probeless.gl.context import create_context, device_name, is_software, pick_device


class FakeContext:
    def __init__(self, vendor: str, renderer: str):
        self.info = {"GL_VENDOR": vendor, "GL_RENDERER": renderer}
        self.released = False

    def release(self):
        self.released = True


LLVMPIPE = ("Mesa/X.org", "llvmpipe (LLVM 15.0.6, 256 bits)")
NVIDIA = ("NVIDIA Corporation", "NVIDIA H200/PCIe/SSE2")


def opener(devices):
    opened = []

    def open_device(i):
        if i >= len(devices):  # what glcontext raises past the last device
            raise Exception(f"requested device index {i}, but found {len(devices)} devices")
        opened.append(FakeContext(*devices[i]))
        return opened[-1]
    return open_device, opened


def test_auto_takes_the_hardware_device_and_releases_the_software_one():
    open_device, opened = opener([LLVMPIPE, NVIDIA])
    index, ctx = pick_device(open_device)
    assert index == 1 and device_name(ctx) == "NVIDIA Corporation NVIDIA H200/PCIe/SSE2" and not is_software(ctx)
    assert opened[0].released and not ctx.released


def test_auto_with_only_software_keeps_device_0_without_reopening_it():
    open_device, opened = opener([LLVMPIPE])
    index, ctx = pick_device(open_device)
    assert index == 0 and ctx is opened[0] and not ctx.released and len(opened) == 1


def test_software_and_an_index_are_obeyed():
    open_device, _ = opener([NVIDIA, LLVMPIPE])
    assert pick_device(open_device, "software")[0] == 1
    assert pick_device(open_device)[0] == 0
    open_device, _ = opener([LLVMPIPE, NVIDIA])
    assert pick_device(open_device, "0")[0] == 0


def test_a_bad_override_is_one_clear_error(monkeypatch):
    monkeypatch.setenv("PROBELESS_GL_DEVICE", "gpu0")
    with pytest.raises(DeviceError, match="PROBELESS_GL_DEVICE='gpu0'"):
        create_context()


@pytest.mark.gl
def test_this_machine_gets_a_working_context():
    ctx = create_context()
    try:
        assert ctx.version_code >= 430 and device_name(ctx)
    finally:
        ctx.release()
