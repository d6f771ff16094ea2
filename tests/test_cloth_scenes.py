"""The benchmark's cloth scenes (benchmarks/cloth_scenes.py): cache keys that stay valid as the scene
specification grows, Blender's cloth presets as Blender ships them, the armature of the sleeve."""

import dataclasses
import hashlib
import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from benchmarks import cloth_scenes
from benchmarks.cloth_scenes import CLOTH_PRESETS, SCENES, Armature, SceneSpec, Wind

#: The cache keys of the scenes baked before material, wind and armature entered the specification:
#: their baked frames in benchmarks/output/ are found by these keys, so a change here re-bakes them.
CACHED_KEYS = {
    "drape_sphere": "326473ff1e1c",
    "flag_wind": "52e3d77230cb",
    "fall_box": "cd7318fa336c",
    "hang_corners": "f2fb39d267ef",
    "drape_sphere_hd": "ce7a7d4f9d52",
    "tablecloth": "dd09166777cc",
    "sheet_cube_50k": "6e69784e5211",
    "sheet_cube_100k": "86542fd9709e",
    "hang_10k": "a3db251dca41",
    "flag_soft_10k": "f1f0fe8b0127",
    "flag_soft_20k": "cf2ca14cc00f",
    "banner_10k": "d8ef4e296cd1",
    "curtain_ball_15k": "a394bdb4c60e",
    "balloon_10k": "3322fb7eaf3c",
    "two_sheets_10k": "1a04de23d1a0",
    "lift_10k": "6aadc0e0c4fe",
}


def _key_of_plain_fields(spec):
    """The key from the fields every spec has, hashed as the cache has always hashed them."""
    blob = [spec.kind, spec.subdivisions, spec.size, spec.frames, spec.quality, spec.params, cloth_scenes._VERSION]
    return hashlib.sha1(json.dumps(blob).encode()).hexdigest()[:12]


@pytest.mark.parametrize("name", sorted(CACHED_KEYS))
def test_earlier_scenes_keep_their_cache_keys(name):
    assert SCENES[name].key() == CACHED_KEYS[name]


def test_specs_without_material_wind_or_armature_hash_their_plain_fields():
    for spec in SCENES.values():
        if not (spec.material or spec.wind or spec.armature):
            assert spec.key() == _key_of_plain_fields(spec), spec.name


def test_material_wind_and_armature_each_enter_the_key():
    base = SceneSpec("x", "flag", (10, 10))
    wind = Wind(location=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0), strength=((1, 1.0),))
    arm = Armature(radius=0.1, extent=(0.0, 1.0), segments=(8, 8), elbow=0.5, blend=0.05, bend_degrees=90.0,
                   bend_frames=(2, 10))
    variants = [
        base,
        dataclasses.replace(base, material=(("mass", 1.0),)),
        dataclasses.replace(base, material=(("mass", 2.0),)),
        dataclasses.replace(base, wind=wind),
        dataclasses.replace(base, wind=dataclasses.replace(wind, seed=1)),
        dataclasses.replace(base, armature=arm),
        dataclasses.replace(base, armature=dataclasses.replace(arm, bend_degrees=45.0)),
    ]
    keys = [v.key() for v in variants]
    assert len(set(keys)) == len(keys)


def test_scenes_with_a_material_use_a_preset_of_blender():
    presets = {name: (quality, material) for name, (quality, material) in CLOTH_PRESETS.items()}
    material_scenes = [s for s in SCENES.values() if s.material]
    assert {s.name for s in material_scenes} >= {"flag_leather_12k", "flag_denim_12k", "sleeve_armature_12k"}
    for spec in material_scenes:
        assert (spec.quality, spec.material) in presets.values(), spec.name


def _blender_preset(path):
    """The ``settings.<attribute> = <number>`` lines of one of Blender's cloth preset scripts."""
    found = re.findall(r"^bpy\.context\.cloth\.settings\.(\w+) = ([-\d.]+)$", path.read_text(), re.MULTILINE)
    return {attribute: float(value) for attribute, value in found}


def test_cloth_presets_match_the_preset_files_blender_ships():
    spec = importlib.util.find_spec("bpy")
    if spec is None:
        pytest.skip("the bpy module is not installed")
    folders = sorted(Path(spec.origin).parent.glob("*/scripts/presets/cloth"))
    if not folders:
        pytest.skip("the bpy module ships no cloth presets")
    for name, (quality, material) in CLOTH_PRESETS.items():
        shipped = _blender_preset(folders[-1] / f"{name.capitalize()}.py")
        assert shipped.pop("quality") == quality, name
        for attribute, value in material:
            assert shipped[attribute] == pytest.approx(value), (name, attribute)


def test_the_sleeve_arm_bends_its_forearm_about_the_elbow():
    pytest.importorskip("bpy")
    spec = SCENES["sleeve_armature_12k"]
    arm = spec.armature
    bpy = cloth_scenes._import_bpy()
    cloth_scenes.build(spec)
    tube = bpy.data.objects["Arm"]

    def arm_at(frame):
        bpy.context.scene.frame_set(frame)
        evaluated = tube.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", co)
        evaluated.to_mesh_clear()
        return co.reshape(-1, 3).astype(np.float64)

    rest, held_still, bent, end = (arm_at(f) for f in (1, arm.bend_frames[0], arm.bend_frames[1], spec.frames))
    upper = rest[:, 0] <= arm.elbow - arm.blend
    fore = rest[:, 0] >= arm.elbow + arm.blend
    # float32 coordinates of unit size: 1e-6 of rounding
    np.testing.assert_allclose(held_still, rest, atol=1e-6)
    np.testing.assert_allclose(bent[upper], rest[upper], atol=1e-6)
    np.testing.assert_allclose(end, bent, atol=1e-6)
    # the forearm turns rigidly about the elbow by the bend angle (the best rotation of its offsets
    # from the elbow fits them to float32 rounding)
    elbow = np.array([arm.elbow, 0.0, 0.0])
    before, after = rest[fore] - elbow, bent[fore] - elbow
    turn, _ = Rotation.align_vectors(after, before)
    np.testing.assert_allclose(turn.apply(before), after, atol=1e-6)
    assert np.degrees(turn.magnitude()) == pytest.approx(arm.bend_degrees, abs=1e-3)
