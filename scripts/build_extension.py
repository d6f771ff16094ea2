"""Validate the extension manifest, or download the bundled wheels and build per-platform zips.

    python scripts/build_extension.py validate
    python scripts/build_extension.py build [--platforms linux-x64 ...] [--output-dir dist]

Runs in an environment with the ``bpy`` module, whose bundled extension CLI (``blender_ext.py``)
does the validating and building, exactly as ``blender --command extension ...`` would.

The committed manifest lists no wheels (a dev checkout uses the venv's SciPy); ``build``
copies the sources to ``build/stage/shape_differences``, downloads the wheels of
``requirements-extension.txt`` for every platform into its ``wheels/``, writes them into the
staged manifest and builds one zip per platform into ``dist/``.
"""

import argparse
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXTENSION_ID = "shape_differences"
REQUIREMENTS = ROOT / "requirements-extension.txt"

#: Blender platform -> pip platform tags, oldest OS first; pip also accepts older tags of each.
PIP_PLATFORMS = {
    "linux-x64": ["manylinux_2_28_x86_64", "manylinux2014_x86_64"],
    "windows-x64": ["win_amd64"],
    "macos-arm64": ["macosx_12_0_arm64", "macosx_14_0_arm64"],
    "macos-x64": ["macosx_12_0_x86_64", "macosx_14_0_x86_64"],
}
#: Never copied into the staging folder (the manifest's paths_exclude_pattern does the rest).
STAGE_IGNORE = shutil.ignore_patterns(".git", ".venv", "wheels", "dist", "build", "demo_output",
                                      "__pycache__", "*.pyc", ".pytest_cache")


def version() -> str:
    """The extension's version, from its manifest."""
    import tomllib
    return tomllib.loads((ROOT / "blender_manifest.toml").read_text(encoding="utf-8"))["version"]


def blender_cli() -> tuple[Path, Path]:
    """Paths of Blender's extension CLI and of its list of valid tags, inside ``bpy``."""
    import bpy
    scripts = Path(bpy.utils.system_resource('SCRIPTS'))
    return (scripts / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py",
            scripts / "modules" / "_bpy_internal" / "extensions" / "tags.py")


def run_cli(*arguments: str):
    cli, _tags = blender_cli()
    subprocess.run([sys.executable, str(cli), *arguments], check=True)


def validate(source: Path):
    _cli, tags = blender_cli()
    run_cli("validate", "--valid-tags", str(tags), str(source))


def pinned_requirements() -> list[tuple[str, str]]:
    """``(name, version)`` of every ``name==version`` line of requirements-extension.txt."""
    lines = (line.split("#")[0].strip() for line in REQUIREMENTS.read_text().splitlines())
    return [tuple(line.split("==")) for line in lines if line]


def download_wheels(platform: str, destination: Path) -> list[Path]:
    """The wheel of every requirement for ``platform`` and CPython 3.11 (downloaded once)."""
    wheels = []
    for name, version in pinned_requirements():
        prefix = f"{name.replace('-', '_').lower()}-{version}-"
        for pip_platform in PIP_PLATFORMS[platform]:
            result = subprocess.run(
                [sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
                 "--only-binary=:all:", "--no-deps", "--python-version", "3.11",
                 "--implementation", "cp", "--platform", pip_platform, "--dest", str(destination),
                 f"{name}=={version}"], capture_output=True, text=True)
            if result.returncode == 0:
                break
        else:
            sys.exit(f"No wheel of {name}=={version} for {platform}:\n{result.stderr}")
        wheels += [wheel for wheel in destination.glob("*.whl")
                   if wheel.name.lower().startswith(prefix)]
    return wheels


def stage_sources(stage: Path, platform: str, wheels: list[Path]):
    """Copy the sources to ``stage`` with ``wheels`` and a manifest listing them for
    ``platform`` only (so a universal2 wheel meant for one Mac never doubles up on the other)."""
    if stage.exists():
        shutil.rmtree(stage)
    shutil.copytree(ROOT, stage, ignore=STAGE_IGNORE)
    (stage / "wheels").mkdir()
    for wheel in wheels:
        shutil.copy2(wheel, stage / "wheels" / wheel.name)
    manifest = stage / "blender_manifest.toml"
    listing = "wheels = [\n" + "".join(f'  "./wheels/{w.name}",\n' for w in wheels) + "]\n\n"
    text = re.sub(r"^platforms = .*$", f'platforms = ["{platform}"]', manifest.read_text(),
                  count=1, flags=re.M)
    manifest.write_text(text.replace("[build]", listing + "[build]", 1))


def build(platforms: list[str], output_dir: Path) -> list[Path]:
    """Download the wheels and build one zip per platform into ``output_dir``."""
    output_dir.mkdir(parents=True, exist_ok=True)
    zips = []
    for platform in platforms:
        cache = ROOT / "wheels" / platform
        cache.mkdir(parents=True, exist_ok=True)
        stage = ROOT / "build" / "stage" / platform / EXTENSION_ID
        stage_sources(stage, platform, download_wheels(platform, cache))
        validate(stage)
        run_cli("build", "--source-dir", str(stage), "--output-dir", str(output_dir),
                "--split-platforms")
        zips += output_dir.glob(f"{EXTENSION_ID}-{version()}-{platform.replace('-', '_')}.zip")  # not older builds
    for path in zips:
        print(f"{path.name}: {path.stat().st_size / 2**20:.1f} MiB")
    return zips


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser("validate", help="validate blender_manifest.toml")
    build_parser = commands.add_parser("build", help="download wheels and build the zips")
    build_parser.add_argument("--platforms", nargs="+", choices=sorted(PIP_PLATFORMS),
                              default=list(PIP_PLATFORMS))
    build_parser.add_argument("--output-dir", type=Path, default=ROOT / "dist")
    arguments = parser.parse_args(argv)
    if arguments.command == "validate":
        validate(ROOT)
    else:
        build(arguments.platforms, arguments.output_dir.resolve())


if __name__ == "__main__":
    os.chdir(ROOT)
    main()
