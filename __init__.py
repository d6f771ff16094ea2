# SPDX-License-Identifier: GPL-3.0-or-later
"""Shape Differences: in-between, exaggerate and rebuild mesh poses from functional shape
differences (Corman et al. 2017). This module only registers; see operators/, ui/ and core/.

The Blender modules are imported inside register() so that importing the package (e.g. when
pytest collects the repository, whose root is this package) does not need bpy.
"""


def register():
    from . import operators, ui

    ui.register()
    operators.register()


def unregister():
    from . import operators, ui

    operators.unregister()
    ui.unregister()
