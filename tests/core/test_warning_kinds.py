"""Every warning of the core has a kind of one documented list (``core.errors.KINDS``, a row each
in docs/errors.md), read from the code itself: a warning no test reaches is held to it too. The
warnings the tests do reach are checked as they are issued (``conftest.every_core_warning_has_a_kind``)."""

import ast
import re
from pathlib import Path

import pytest

from core.errors import KINDS, ShapeDifferenceWarning, shape_warning, warn

ROOT = Path(__file__).resolve().parents[2]
#: The core's functions that make or issue a warning, and where their ``kind`` argument is.
WARNERS = {"warn": 1, "shape_warning": 1, "said_warning": 1, "warn_said": 1}


def _calls(name):
    """``(file, line, call)`` of every call to ``name`` (a function, or ``module.function``) in core/."""
    for path in sorted((ROOT / "core").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call):
                func = node.func
                dotted = isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name)
                called = func.id if isinstance(func, ast.Name) else \
                    f"{func.value.id}.{func.attr}" if dotted else None
                if called == name:
                    yield path.name, node.lineno, node


def test_the_core_warns_only_through_the_one_function_that_gives_each_warning_a_kind():
    """No module of the core calls ``warnings.warn`` or makes a ``ShapeDifferenceWarning`` but
    :mod:`core.errors`, whose :func:`~core.errors.warn` and :func:`~core.errors.shape_warning` set a
    kind of :data:`~core.errors.KINDS`; each call that names its kind names one of them."""
    direct = [(f, line) for name in ("warnings.warn", "ShapeDifferenceWarning") for f, line, _ in _calls(name)
              if f != "errors.py"]
    assert not direct, f"warnings made or issued outside core.errors.warn (no kind): {direct}"
    named = []
    for name, place in WARNERS.items():
        for f, line, call in _calls(name):
            kind = call.args[place] if len(call.args) > place else \
                next((k.value for k in call.keywords if k.arg == "kind"), None)
            if isinstance(kind, ast.Constant):
                named.append((f, line, kind.value))
    unknown = [(f, line, kind) for f, line, kind in named if kind not in KINDS]
    assert named and not unknown, unknown


def test_each_kind_has_a_row_in_the_documented_list():
    """docs/errors.md lists each kind with what it is about, as :data:`~core.errors.KINDS` does."""
    text = (ROOT / "docs" / "errors.md").read_text(encoding="utf-8")
    table = text[text.index("| `kind` | About |"):].split("\n\n")[0]
    rows = dict(re.findall(r"^\| `([a-z_]+)` \| (.+) \|$", table, flags=re.M)[1:])  # after the header
    assert set(rows) == set(KINDS), set(rows) ^ set(KINDS)


def test_a_warning_s_kind_is_one_of_the_list_and_survives_being_raised():
    """:func:`~core.errors.warn` gives the warning its kind, also where warnings are errors (a
    pipeline's ``simplefilter("error")``), and refuses a kind not in the list (a mistake of the code)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        with pytest.raises(ShapeDifferenceWarning) as raised:
            warn("The poses are alike.", "same_poses")
    assert raised.value.kind == "same_poses" and str(raised.value) == "The poses are alike."
    with pytest.raises(ValueError, match="no kind of warning"):
        shape_warning("x", "nonsense")
