"""The C allocator tuning of core/allocator.py."""

from core.allocator import keep_heap


def test_keep_heap_takes_effect_on_glibc_once(monkeypatch):
    import platform
    import sys
    import types

    import core.allocator as allocator

    monkeypatch.setattr(allocator, "_held", None)
    interactive = types.SimpleNamespace(app=types.SimpleNamespace(background=False))
    monkeypatch.setitem(sys.modules, "bpy", interactive)
    assert not keep_heap()  # an interactive Blender keeps its allocator's settings
    monkeypatch.setitem(sys.modules, "bpy", types.SimpleNamespace(app=types.SimpleNamespace(background=True)))
    first = keep_heap()
    assert keep_heap() == first
    assert bool(first) == (sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc")
    assert first <= frozenset(allocator.SETTINGS)  # names of SETTINGS (a glibc may refuse one: the next test)


def test_a_setting_glibc_refuses_leaves_the_others_in_force(monkeypatch):
    """A glibc that refuses the 64 MB mmap threshold (some versions cap it at HEAP_MAX_SIZE / 2)
    still gets the trim threshold and the arena cap, and ``keep_heap`` says which held. Before,
    the first refusal stopped it: neither of the other two was set and it said none held."""
    import sys
    import types

    import core.allocator as allocator

    made = []

    def mallopt(parameter, value):  # glibc's answer: 1 where the setting is taken, 0 where refused
        made.append((parameter, value))
        return int(parameter != allocator._M_MMAP_THRESHOLD)

    monkeypatch.setattr(allocator, "_held", None, raising=False)
    monkeypatch.setattr(allocator, "_done", False, raising=False)  # the flag before _held
    monkeypatch.setattr(allocator, "_glibc", lambda: types.SimpleNamespace(mallopt=mallopt))
    monkeypatch.setitem(sys.modules, "bpy", types.SimpleNamespace(app=types.SimpleNamespace(background=True)))
    held = allocator.keep_heap()
    asked = [(allocator._M_MMAP_THRESHOLD, allocator.MMAP_THRESHOLD), (allocator._M_TRIM_THRESHOLD,
             allocator.TRIM_THRESHOLD), (allocator._M_ARENA_MAX, allocator.ARENA_MAX)]
    assert sorted(made) == sorted(asked)  # each one asked for, once
    assert held == {"M_TRIM_THRESHOLD", "M_ARENA_MAX"}
    assert allocator.keep_heap() == held and len(made) == 3  # once per process


def test_the_c_library_is_looked_for_once_per_process_where_it_is_not_glibc():
    """Under another C library than glibc (musl: Alpine containers) ``keep_heap`` found nothing to
    tune and looked again at every sequence built, ``platform.libc_ver`` reading the interpreter's
    binary each time (as ``give_back_heap`` did at each idle worker's rest): three of each looked six
    times. A fresh process (the library found is kept for the process) told it is not glibc looks once
    and tunes nothing."""
    import subprocess
    import sys
    from pathlib import Path

    import core.allocator as allocator

    script = ("import platform, sys\n"
              "looked = []\n"
              "platform.libc_ver = lambda *args, **kwargs: looked.append(1) or ('musl', '1.2.4')\n"
              "sys.platform = 'linux'\n"
              "from core import allocator\n"
              "tuned = [allocator.keep_heap() or allocator.give_back_heap() for _ in range(3)]\n"
              "print(len(looked), any(tuned))\n")
    root = Path(allocator.__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, "-c", script], cwd=root, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["1", "False"], out
