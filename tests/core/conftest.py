import sys
from pathlib import Path

import pytest

from inbetween_helpers import _strip

# `import core` from the repository root, as scripts and the extension do.
ROOT = str(Path(__file__).resolve().parents[2])
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)


@pytest.fixture(scope="module")
def strip():
    return _strip()


@pytest.fixture(autouse=True)
def every_core_warning_has_a_kind(monkeypatch):
    """Records every :class:`core.ShapeDifferenceWarning` the core issues while a test runs (also
    those the test catches itself) and fails the test where one has no ``kind`` of
    :data:`core.errors.KINDS`: the operators, ``python -m core`` and pipelines sort warnings by it.
    Warnings a test issues itself are left out (a test of how a kindless warning is printed)."""
    import warnings

    from core.errors import KINDS, ShapeDifferenceWarning

    issued = []
    real = warnings.warn

    def recording(message, category=None, stacklevel=1, source=None):
        about = message if isinstance(message, Warning) else None
        sort = type(message) if about is not None else category
        if isinstance(sort, type) and issubclass(sort, ShapeDifferenceWarning) and \
                sys._getframe(1).f_globals.get("__name__", "").startswith("core"):
            issued.append((getattr(about, "kind", None), str(message)))
        return real(message, category, stacklevel + 1, source)

    monkeypatch.setattr(warnings, "warn", recording)
    yield issued
    kindless = [message for kind, message in issued if kind not in KINDS]
    assert not kindless, f"warnings of the core without a kind of core.errors.KINDS: {kindless}"


@pytest.fixture
def own_pool(monkeypatch):
    """A thread pool of its own (:mod:`core.concurrency`) for a test that patches
    ``available_cores``: the pool it makes is sized for the patched cores, so it is shut down after
    the test and the process's pool (or none) given back, rather than kept for the tests after it."""
    import core.concurrency as concurrency

    monkeypatch.setattr(concurrency, "_pool", None)
    monkeypatch.setattr(concurrency, "_pool_threads", 0)
    yield
    with concurrency._pool_lock:
        pool = concurrency._pool
    if pool is not None:
        pool.shutdown(wait=True)  # outside the lock: a piece still finishing may take it
