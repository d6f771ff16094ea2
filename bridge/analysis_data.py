"""What the analysis operators store on a mesh or object: attributes (distortion maps) written and
removed from a copy, and the shape space kept as a custom property.
"""

from __future__ import annotations

import re

import bpy
import numpy as np

#: The names of the attributes the analysis operators write (operators/analysis.py, distortion
#: maps): colours "SD Area", "SD Conformal", "SD Bending", "SD Eigen Offset Area 2", values
#: "sd_area", "sd_area_face", each alone (a key's) or with the frame mapped (" f12"). Exact names,
#: not prefixes: a user's own "sd_mask" or "SD Paint" is no map.
ANALYSIS_ATTRIBUTE = re.compile(r"(SD (Area|Conformal|Bending|Eigen (Offset )?(Area|Conformal) \d+)"
                                r"|sd_(area|conformal|bending)(_face)?)( f-?\d+)?")


def forget_analysis(mesh: bpy.types.Mesh) -> None:
    """Remove from ``mesh`` (a copy of a source's mesh, for a new object playing other poses) the
    distortion maps of the source's poses and every custom property (a pipeline's asset tags
    stay with the source; the frame maps' list would show the source's maps on the new object)."""
    for attribute in [a.name for a in mesh.attributes if ANALYSIS_ATTRIBUTE.fullmatch(a.name)]:
        mesh.attributes.remove(mesh.attributes[attribute])
    for key in list(mesh.keys()):
        del mesh[key]


#: Custom property (on the object) holding the last shape space (operators/analysis.py).
SHAPE_SPACE_PROPERTY = "shape_space"


def stored_shape_space(obj) -> dict | None:
    """The shape space last stored on ``obj`` as a plain dict, or None."""
    if obj is None or SHAPE_SPACE_PROPERTY not in obj:
        return None
    data = obj[SHAPE_SPACE_PROPERTY]
    return data.to_dict() if hasattr(data, "to_dict") else dict(data)


def write_attribute(mesh, name: str, domain: str, values: np.ndarray, *, color: bool = False):
    """Create or overwrite one attribute (FLOAT, or FLOAT_COLOR when ``color``) of ``mesh``."""
    kind = 'FLOAT_COLOR' if color else 'FLOAT'
    existing = mesh.attributes.get(name)
    if existing is not None and (existing.data_type != kind or existing.domain != domain):
        mesh.attributes.remove(existing)
        existing = None
    if existing is None:
        existing = (mesh.color_attributes.new(name, kind, domain) if color
                    else mesh.attributes.new(name, kind, domain))
    existing.data.foreach_set("color" if color else "value", np.ascontiguousarray(values, dtype=np.float32).ravel())
    return existing
