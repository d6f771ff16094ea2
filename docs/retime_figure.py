"""Draws docs/images/retime_tip.png: a corner of an armature-deformed strip over time, the source's
frames against a retime from every 4th frame at half speed (run with the dev venv's Python)."""

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "scripts"), str(ROOT / "tests" / "blender")]

import dev_extension  # noqa: E402  (before bpy: a temporary Blender user folder)
import bpy  # noqa: E402
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from blender_scenes import armature_scene, evaluated_frames  # noqa: E402


def main():
    extension = dev_extension.enable()
    bpy.ops.wm.read_homefile(use_empty=True)
    source = armature_scene(frames=25)
    bridge = extension.bridge
    frames = evaluated_frames(bridge, source, range(1, 26))
    tip = int(np.argmax(frames[1][:, 0] + frames[1][:, 1]))
    path = Path(tempfile.mkdtemp()) / "retime.pc2"
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=25, frame_step=4, speed=0.5,
                                     filepath=str(path))
    from importlib import import_module
    cache = import_module(f"{extension.__name__}.core.point_cache").read_pc2(path)
    times = 1 + 0.5 * np.arange(cache.n_samples)

    figure, axis = plt.subplots(figsize=(7, 3.2), dpi=120)
    axis.plot(times, cache.positions[:, tip, 2], "-", color="tab:blue", lw=1.5,
              label=f"retimed, speed 0.5 ({cache.n_samples} frames)")
    axis.plot(times, cache.positions[:, tip, 2], ".", color="tab:blue", ms=4)
    source_z = [frames[f][tip, 2] for f in range(1, 26)]
    axis.plot(range(1, 26), source_z, "x", color="0.3", label="source frames (25)")
    axis.plot(range(1, 26, 4), source_z[::4], "o", mfc="none", mec="tab:red", ms=9,
              label="kept (key) frames: exact")
    axis.set_xlabel("source time (frame)")
    axis.set_ylabel("tip height")
    axis.set_title("Retime from every 4th frame at half speed: an armature-deformed strip")
    axis.legend(frameon=False, fontsize=8)
    figure.tight_layout()
    out = ROOT / "docs" / "images" / "retime_tip.png"
    figure.savefig(out)
    print(out)


if __name__ == "__main__":
    main()
