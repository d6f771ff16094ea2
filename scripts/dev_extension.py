"""Load this checkout into the ``bpy`` module as Blender loads an installed extension: a user
extension repository whose folder holds a ``shape_differences`` link to the checkout (whatever
the checkout's own folder is called). Used by the tests and the demo.

Import this before ``bpy``: it points ``BLENDER_USER_RESOURCES`` at a temporary folder so the
user's own Blender configuration is never read or written.
"""

import os
import sys
import tempfile
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
EXTENSION_ID = "shape_differences"
REPO_MODULE = "dev"
MODULE = f"bl_ext.{REPO_MODULE}.{EXTENSION_ID}"

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="shape-diff-user-"))


def _raise(error):
    raise error


def enable():
    """Enable the checkout as ``bl_ext.dev.shape_differences`` and return that module."""
    import bpy
    import addon_utils  # importable once bpy is

    if MODULE in sys.modules and hasattr(bpy.types.Scene, "shape_differences"):
        return sys.modules[MODULE]
    parent = Path(tempfile.mkdtemp(prefix="shape-diff-repo-"))
    (parent / EXTENSION_ID).symlink_to(REPO_ROOT, target_is_directory=True)
    bpy.context.preferences.extensions.repos.new(
        name=REPO_MODULE, module=REPO_MODULE, custom_directory=str(parent), source='USER')
    addon_utils.enable(MODULE, default_set=True, handle_error=_raise)
    if MODULE not in sys.modules:
        raise RuntimeError(f"{MODULE} did not load")
    return sys.modules[MODULE]


def disable():
    import bpy  # noqa: F401
    import addon_utils
    addon_utils.disable(MODULE, default_set=True, handle_error=_raise)
