"""Fixtures that load the extension into the PyPI ``bpy`` module the way Blender does (see
scripts/dev_extension.py), and an empty scene per test."""

import importlib
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))

import dev_extension  # noqa: E402  (sets BLENDER_USER_RESOURCES before bpy is imported)
from dev_extension import MODULE, REPO_ROOT  # noqa: E402,F401


@pytest.fixture(scope="session")
def extension():
    """The enabled extension's top-level module (``bl_ext.dev.shape_differences``)."""
    pytest.importorskip("bpy")
    module = dev_extension.enable()
    yield module
    dev_extension.disable()


@pytest.fixture(scope="session")
def core(extension):
    """The extension's core, skipping while it lacks the facade the operators use."""
    module = importlib.import_module(f"{MODULE}.core")
    missing = []
    for name in ("Interpolator", "SequenceInterpolator", "shape_differences", "reconstruct",
                 "ShapeDifferenceError", "MeshError"):
        try:
            getattr(module, name)
        except (AttributeError, ImportError):
            missing.append(name)
    if missing:
        pytest.skip(f"core does not provide {', '.join(missing)} yet")
    return module


@pytest.fixture
def bpy_empty(extension):
    """An empty scene for each test."""
    import bpy
    bpy.ops.wm.read_homefile(use_empty=True)
    return bpy
