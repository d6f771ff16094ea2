"""The C allocator tuning of core/allocator.py."""

from core.allocator import keep_heap


def test_keep_heap_takes_effect_on_glibc_once(monkeypatch):
    import platform
    import sys
    import types

    import core.allocator as allocator

    monkeypatch.setattr(allocator, "_done", False)
    interactive = types.SimpleNamespace(app=types.SimpleNamespace(background=False))
    monkeypatch.setitem(sys.modules, "bpy", interactive)
    assert not keep_heap()  # an interactive Blender keeps its allocator's settings
    monkeypatch.setitem(sys.modules, "bpy", types.SimpleNamespace(app=types.SimpleNamespace(background=True)))
    first = keep_heap()
    assert keep_heap() == first
    assert first == (sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc")
