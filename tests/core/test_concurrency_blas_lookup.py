"""threadpoolctl's look-up of the BLAS libraries (core.concurrency's controller) beside threads that
load libraries: the core makes it as it is imported, before any thread of its own exists, and the
threadpoolctl the extension bundles lets a thread that is not the core's (another add-on's, Blender's)
load a library while it runs. Before threadpoolctl 3.7 the look-up ran Python inside glibc's
``dl_iterate_phdr``, under the loader's lock, and a library loaded meanwhile by a thread holding
Python's lock stopped both for ever (session 79's gap worker; threadpoolctl's issue #239).

Each test runs a fresh interpreter (the look-up is made once per process), on this one's ``sys.path``."""

from __future__ import annotations

import ast
import os
import subprocess
import sys

import pytest

pytest.importorskip("threadpoolctl")

#: Seconds a fresh interpreter may take to import the core and answer (a loaded machine's); a
#: deadlocked one never answers.
ANSWER_SECONDS = 120


def _answer(script: str) -> str:
    """The last line ``script`` prints in a fresh interpreter given this one's ``sys.path`` (its
    ``argv``); fails the test where it has not ended within :data:`ANSWER_SECONDS`."""
    path = [os.path.abspath(entry) if entry else os.getcwd() for entry in sys.path]
    try:
        done = subprocess.run([sys.executable, "-c", "import sys\nsys.path[:] = sys.argv[1:]\n" + script, *path],
                              capture_output=True, text=True, timeout=ANSWER_SECONDS)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the interpreter had not ended after {ANSWER_SECONDS} s: a deadlock")
    assert done.returncode == 0, done.stderr
    return done.stdout.strip().splitlines()[-1]


#: Records every look-up (``ThreadpoolController._load_libraries``) with its thread's name and the
#: threads alive then; then the core is imported and its first computation runs in a thread of the
#: caller's, as a modal operator's in Blender (operators.base.worker) and a pipeline's.
RECORDED_LOOKUPS = """
import threading
import threadpoolctl
looked = []
_load = threadpoolctl.ThreadpoolController._load_libraries
def _recorded(self):
    looked.append((threading.current_thread().name, sorted(t.name for t in threading.enumerate())))
    return _load(self)
threadpoolctl.ThreadpoolController._load_libraries = _recorded
from concurrent.futures import ThreadPoolExecutor
import core
from meshes import drape, grid
flat, triangles = grid(12)
with ThreadPoolExecutor(1, thread_name_prefix="caller-worker") as worker:
    worker.submit(core.interpolate, flat, drape(flat), triangles, 0.5).result()
print(looked)
"""


def test_the_blas_look_up_is_made_as_the_core_is_imported_before_any_thread_of_its():
    """The core's one look-up runs in the thread that imports it, the only thread then; none runs in
    the caller's worker thread that computes (nor in the core's pool). At HEAD 9aab0f9 it ran at the
    first computation, in that worker thread, beside the importing one (``[('caller-worker_0',
    ['MainThread', 'caller-worker_0'])]``): with a threadpoolctl before 3.7 (a pipeline's own) a
    library loaded meanwhile by the main thread (Blender's UI, an add-on's import) deadlocked both."""
    looked = ast.literal_eval(_answer(RECORDED_LOOKUPS))
    assert looked == [("MainThread", ["MainThread"])]


#: A thread that is not the core's waits until threadpoolctl's look-up (made at the core's first
#: use) has begun, then imports an extension module not loaded yet (``dlopen`` holding Python's
#: lock); the look-up's per-library step is held until that module is loaded (at most 60 s). Prints
#: whether it was loaded during the hold, or "none" where no such module is found.
LOADED_DURING_THE_LOOKUP = """
import importlib.machinery, importlib.util, threading, time
import threadpoolctl
candidates = ("_sqlite3", "_curses", "mmap", "_decimal", "_testcapi")
extension = tuple(importlib.machinery.EXTENSION_SUFFIXES)
found = [name for name in candidates if name not in sys.modules
         and (spec := importlib.util.find_spec(name)) is not None and (spec.origin or "").endswith(extension)]
if not found:
    print("none")
    raise SystemExit
target, looking, held = found[0], threading.Event(), []
_make = threadpoolctl.ThreadpoolController._make_controller_from_path
def _held(self, filepath):
    if not looking.is_set():
        looking.set()
        deadline = time.monotonic() + 60
        while target not in sys.modules and time.monotonic() < deadline:
            time.sleep(0.01)
        held.append(target in sys.modules)
    return _make(self, filepath)
threadpoolctl.ThreadpoolController._make_controller_from_path = _held
def other():
    looking.wait()
    __import__(target)
threading.Thread(target=other, daemon=True, name="another-add-on").start()
import core
with core.concurrency.single_threaded_blas():
    pass
print(held)
"""


def test_another_thread_loads_a_library_while_the_core_looks_its_blas_up():
    """Another add-on's thread imports an extension module while the core's look-up is under way:
    both go on, the module loaded during the look-up. With threadpoolctl 3.5.0 (the pin at HEAD
    9aab0f9) the interpreter never ended (the look-up's Python callback waiting for Python's lock
    inside ``dl_iterate_phdr``, the import's ``dlopen`` for the loader's lock); 3.7.0 lists the
    libraries from ``/proc/self/maps`` on Linux. A failure here with the venv's threadpoolctl older
    than requirements-extension.txt's: reinstall it (``make install``)."""
    answer = _answer(LOADED_DURING_THE_LOOKUP)
    if answer == "none":
        pytest.skip("no extension module left to load in a fresh interpreter")
    assert ast.literal_eval(answer) == [True]
