"""The farm job definitions: the Open Job Description template passes `openjd check` and its
chunked run (`openjd run`, two chunks, then the merge) writes the single-process cache (to round-off);
the Flamenco job type is valid JavaScript and the commands it authors, run in order, do too."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from core.__main__ import main
from core.obj_file import write_obj
from core.point_cache import read_pc2, write_pc2

ROOT = Path(__file__).resolve().parents[2]
TEMPLATE = ROOT / "farm" / "retime.openjd.yaml"
JOB_TYPE = ROOT / "farm" / "shape-differences-retime.js"
OPENJD = shutil.which("openjd", path=str(Path(sys.executable).parent)) or shutil.which("openjd")
NODE = shutil.which("node")


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    """A small rolling-sheet cache, its OBJ, and the single-process retime of it."""
    folder = tmp_path_factory.mktemp("farm")
    n = 5
    xs, ys = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    rest = np.stack([xs.ravel(), ys.ravel(), np.zeros(n * n)], axis=1)
    triangles = [[j * n + i, j * n + i + 1, (j + 1) * n + i + 1] for j in range(n - 1) for i in range(n - 1)]
    triangles += [[j * n + i, (j + 1) * n + i + 1, (j + 1) * n + i] for j in range(n - 1) for i in range(n - 1)]
    frames = []
    for bend in np.linspace(0.3, 2.0, 9):
        theta = rest[:, 0] * bend
        frames.append(np.stack([np.sin(theta) / bend, rest[:, 1], (1 - np.cos(theta)) / bend], axis=1))
    cache = write_pc2(folder / "in.pc2", np.array(frames), start=1.0)
    topology = write_obj(folder / "sheet.obj", rest, np.array(triangles))
    single = folder / "single.pc2"
    assert main(["retime", str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5",
                 "-q", "-o", str(single)]) == 0
    return folder, cache, topology, single


def _same_frames(path, single):
    """The farm's cache holds the single process's frames with its header, to round-off: on AVX-512
    machines NumPy's and OpenBLAS's small products choose kernels by memory alignment, so two
    processes can differ in the last bit of a float32."""
    farm, whole = read_pc2(path), read_pc2(single)
    assert farm.positions.shape == whole.positions.shape
    assert (farm.start, farm.sampling) == (whole.start, whole.sampling)
    np.testing.assert_allclose(farm.positions, whole.positions, rtol=0, atol=1e-6)


def _openjd_command(parameters: dict, step="Merge", dependencies=True) -> list[str]:
    command = [OPENJD, "run", str(TEMPLATE), "--step", step] + (["--run-dependencies"] if dependencies else [])
    for key, value in parameters.items():
        command += ["-p", f"{key}={value}"]
    return command


@pytest.mark.skipif(OPENJD is None, reason="openjd-cli is not installed (requirements-dev.txt)")
def test_openjd_template_checks():
    result = subprocess.run([OPENJD, "check", str(TEMPLATE)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and "passes validation" in result.stdout, result.stdout + result.stderr


@pytest.mark.skipif(OPENJD is None, reason="openjd-cli is not installed (requirements-dev.txt)")
def test_openjd_two_chunks_equal_the_single_process(job):
    """... from a studio's long path (the job name once held it, past OpenJD's 128 characters)
    into a chunk folder with '#' in its name (once renumbered by the merge with the chunks), on a
    worker whose PYTHONPATH its Python needs (where a studio's Python finds NumPy and SciPy): every
    task's Python still sees it (before, the job set PYTHONPATH to the extension's folder, replacing
    the worker's, and a Python finding NumPy there failed every task: "No module named 'numpy'")."""
    folder, cache, topology, single = job
    worker = folder / "worker site-packages"  # stands for the worker's own module path
    worker.mkdir()
    (worker / "sitecustomize.py").write_text(  # Python imports it at start-up from its module path
        "import pathlib, sys\n"
        "with open(pathlib.Path(__file__).with_name('started.txt'), 'a') as log:\n"
        "    log.write(' '.join(sys.orig_argv[1:]) + '\\n')\n")
    paths = [str(worker)] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])
    shot = folder / ("shot_" + "x" * 100)
    chunks = shot / "take#12"
    chunks.mkdir(parents=True)
    long_cache = shutil.copy(cache, shot / "in.pc2")
    parameters = dict(InputCache=long_cache, Topology=topology, OutputCache=folder / "farm.pc2",
                      ChunkDirectory=chunks, ExtensionDirectory=ROOT, Python=sys.executable,
                      Step=4, Speed=0.5, Chunks=2)
    result = subprocess.run(_openjd_command(parameters), capture_output=True, text=True, timeout=600,
                            env={**os.environ, "PYTHONPATH": os.pathsep.join(paths)})
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert sorted(p.name for p in chunks.iterdir()) == ["chunk1.pc2", "chunk1.pc2.json", "chunk2.pc2",
                                                         "chunk2.pc2.json"]
    _same_frames(folder / "farm.pc2", single)
    started = (worker / "started.txt").read_text().splitlines()
    assert sorted(command for line in started for command in ("retime", "merge") if f" {command} " in line) == \
        ["merge", "retime", "retime"], started


@pytest.mark.skipif(OPENJD is None, reason="openjd-cli is not installed (requirements-dev.txt)")
def test_openjd_takes_a_folder_that_is_no_text_through_a_link_named_in_utf8(job, tmp_path):
    """A shot folder whose name is Latin-1 bytes on a UTF-8 system ('caf\\xe9 shot'): an OpenJD job
    is Unicode text and cannot hold the name, and openjd-cli stops with a traceback and exit
    status 1 before any task runs, writing nothing (what pipeline.md says). Through a symbolic
    link with a UTF-8 name to the folder (the way out it gives) the job runs, and its output is
    the single process's."""
    folder, cache, topology, single = job
    shot = Path(os.fsdecode(bytes(tmp_path) + b"/caf\xe9 shot"))
    (shot / "chunks").mkdir(parents=True)
    shutil.copy(cache, shot / "in.pc2")
    shutil.copy(topology, shot / "sheet.obj")
    link = tmp_path / "cafe_shot"
    link.symlink_to(shot, target_is_directory=True)
    for where, status in ((shot, 1), (link, 0)):
        parameters = dict(InputCache=where / "in.pc2", Topology=where / "sheet.obj", OutputCache=where / "out.pc2",
                          ChunkDirectory=where / "chunks", ExtensionDirectory=ROOT, Python=sys.executable,
                          Step=4, Speed=0.5, Chunks=2)
        result = subprocess.run(_openjd_command(parameters), capture_output=True, timeout=600)
        log = result.stdout[-3000:] + result.stderr[-3000:]  # said with any assertion below
        assert result.returncode == status, log
        if status:
            assert b"UnicodeEncodeError" in result.stdout + result.stderr, log
            assert sorted(p.name for p in shot.iterdir()) == ["chunks", "in.pc2", "sheet.obj"], log
            assert not list((shot / "chunks").iterdir()), log
    _same_frames(shot / "out.pc2", single)


def test_jobs_sharing_a_chunk_folder_are_refused_not_mixed(job, capsys):
    """Two takes of one cloth (same mesh and frames, other motion) retimed by two jobs that share a
    chunk folder, their tasks interleaved as a farm runs them: before, the merge succeeded with the
    other take's chunk in it (a probe's two takes of a 36-vertex sheet: 15 and 17 of 33 samples
    wrong, up to 0.17 and 0.41 of the sheet's width); now it is refused, and so is a chunk file
    another job wrote over after its stamp, and a set of chunks without its last."""
    folder, cache, topology, single = job
    other = read_pc2(cache).positions.copy()
    other[1:, :, 2] *= 1.5  # another take: the same mesh and frames, the sheet rolled further
    take_b = write_pc2(folder / "take_b.pc2", other, start=1.0)
    chunks = folder / "shared"

    def chunk(take, index, count=2, into=chunks):
        return main(["retime", str(take), "--topology", str(topology), "--step", "4", "--speed", "0.5",
                     "--chunk", f"{index}/{count}", "-q", "-o", str(into / f"chunk{index}.pc2")])

    def merge(name, count=2):
        return main(["merge", "--numbered", str(chunks / "chunk#.pc2"), "--count", str(count),
                     "-o", str(folder / name)])

    assert chunk(cache, 1) == chunk(take_b, 1) == chunk(take_b, 2) == chunk(cache, 2) == 0
    capsys.readouterr()
    assert merge("take_a_farm.pc2") == 2
    assert "is a chunk of another retime" in capsys.readouterr().err
    assert not (folder / "take_a_farm.pc2").exists()

    assert chunk(cache, 1) == 0 and merge("take_a_farm.pc2") == 0  # the job's own chunks, re-run
    _same_frames(folder / "take_a_farm.pc2", single)
    assert chunk(take_b, 2, into=folder) == 0
    shutil.copy(folder / "chunk2.pc2", chunks / "chunk2.pc2")  # written over by another job, stamp left
    capsys.readouterr()
    assert merge("written_over.pc2") == 2
    assert "is not the file its stamp" in capsys.readouterr().err
    assert not (folder / "written_over.pc2").exists()

    assert chunk(cache, 1, 3) == chunk(cache, 2, 3) == 0
    capsys.readouterr()
    assert merge("missing_last.pc2") == 2  # chunks 1 and 2 of 3: before, merged without the last gap
    assert "the last chunk(s) are missing" in capsys.readouterr().err


def _other_jobs_chunks(cache, topology, chunks, count):
    """The complete chunk set of another job on the same cache (speed 0.25 instead of 0.5) in ``chunks``:
    what a job sharing the folder leaves there when it runs all its chunks between this job's chunks
    and this job's merge."""
    chunks.mkdir()
    for index in range(1, count + 1):
        assert main(["retime", str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.25",
                     "--chunk", f"{index}/{count}", "-q", "-o", str(chunks / f"chunk{index}.pc2")]) == 0


@pytest.mark.skipif(OPENJD is None, reason="openjd-cli is not installed (requirements-dev.txt)")
def test_openjd_merge_refuses_another_jobs_whole_chunk_set(job):
    """Two jobs sharing a chunk folder, the other job's chunks replacing every one of this job's before
    its merge: those chunks agree among themselves, so before, the merge wrote the other job's retime
    and exited 0 (two `openjd run` at once, speeds 0.5 and 0.25: 97 samples instead of 49). The merge
    now gets the job's input and settings and refuses chunks of any other retime, naming the folder."""
    folder, cache, topology, single = job
    chunks = folder / "shared by two jobs"
    _other_jobs_chunks(cache, topology, chunks, 2)
    output = folder / "openjd_other.pc2"
    parameters = dict(InputCache=cache, Topology=topology, OutputCache=output, ChunkDirectory=chunks,
                      ExtensionDirectory=ROOT, Python=sys.executable, Step=4, Speed=0.5, Chunks=2)
    result = subprocess.run(_openjd_command(parameters, dependencies=False), capture_output=True, text=True,
                            timeout=600)
    log = result.stdout + result.stderr
    assert result.returncode != 0, log[-3000:]
    assert f"another job has written into the chunk folder '{chunks}'" in log, log[-3000:]
    assert not output.exists()


def test_merge_knows_its_retime(job, capsys):
    """`merge --retime CACHE` with the retime's settings: its own chunks merge into the single
    process's file, also with the input and the OBJ seen under other paths (a farm's path mapping
    gives each worker its own); another retime's complete chunk set (same cache, another speed), a
    plain cache given as a part, and settings without --retime are refused with exit status 2 and
    no output."""
    folder, cache, topology, single = job
    own, other = folder / "own", folder / "other"
    own.mkdir()
    for index in (1, 2):
        assert main(["retime", str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5",
                     "--chunk", f"{index}/2", "-q", "-o", str(own / f"chunk{index}.pc2")]) == 0
    _other_jobs_chunks(cache, topology, other, 2)

    def merge(chunks, name, *extra):
        return main(["merge", "--numbered", str(chunks / "chunk#.pc2"), "--count", "2", "-o", str(folder / name),
                     *extra])

    job_of = ["--retime", str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5"]
    assert merge(own, "own.pc2", *job_of) == 0
    _same_frames(folder / "own.pc2", single)
    mapped = folder / "mapped"
    mapped.mkdir()
    assert merge(own, "mapped.pc2", "--retime", str(shutil.copy(cache, mapped / "cloth.pc2")), "--topology",
                 str(shutil.copy(topology, mapped / "cloth.obj")), *job_of[4:]) == 0
    assert (folder / "mapped.pc2").read_bytes() == (folder / "own.pc2").read_bytes()
    capsys.readouterr()
    assert merge(other, "other.pc2", *job_of) == 2
    error = capsys.readouterr().err
    assert "another input cache, topology or setting" in error and f"chunk folder '{other}'" in error
    assert not (folder / "other.pc2").exists()
    assert main(["merge", str(single), "-o", str(folder / "plain.pc2"), *job_of]) == 2
    assert "it has no stamp" in capsys.readouterr().err
    assert merge(own, "no_retime.pc2", *job_of[2:]) == 2  # settings without the input they belong to
    assert "--topology goes with --retime" in capsys.readouterr().err
    for setting in (["--speed", "0.5"], ["--k-m", "20"], ["--k-n", "20"], ["--intrinsic"], ["--linear"],
                    ["--start", "3"], ["--offset", "0.1"]):  # ignored without --retime, so refused
        assert merge(own, "no_retime.pc2", *setting) == 2
        assert f"{setting[0]} goes with --retime" in capsys.readouterr().err
    assert merge(own, "no_step.pc2", *job_of[:4]) == 2
    assert "needs the retime's --topology and --step" in capsys.readouterr().err
    assert not any((folder / name).exists() for name in ("plain.pc2", "no_retime.pc2", "no_step.pc2"))


CANCELLED_MERGE = """
import os, signal, sys
import core.point_cache as point_cache
from core.__main__ import main

point_cache.MERGE_BLOCK_BYTES = 64  # many small blocks: the merge is cancelled with some written
write = point_cache.write_atomically

def cancelled_midway(path, blocks):
    def sent():
        for index, block in enumerate(blocks):
            if index == 3:
                os.kill(os.getpid(), signal.SIGTERM)  # a farm cancelling the task
            yield block
    return write(path, sent())

point_cache.write_atomically = cancelled_midway
sys.exit(main(sys.argv[1:]))
"""


def test_a_cancelled_merge_leaves_no_partial_file(job, tmp_path):
    """SIGTERM while the output is being written (how a farm cancels a task, with the template's
    NOTIFY_THEN_TERMINATE): the command exits non-zero and removes its temporary file (before,
    Python died on the spot and left a hidden half-written '.out.pc2.*' beside the output, up to
    the output's size). The task's log says so in one line, as for Ctrl+C (it said nothing)."""
    folder, cache, topology, single = job
    output = tmp_path / "out" / "shot.pc2"
    result = subprocess.run([sys.executable, "-c", CANCELLED_MERGE, "merge", str(single), "-o", str(output)],
                            cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 128 + 15, result.stderr
    assert list(output.parent.iterdir()) == []
    assert result.stderr.splitlines() == ["merge: cancelled (SIGTERM), nothing written"]


def test_openjd_tasks_are_cancelled_with_sigterm_first():
    """Every action of the template is cancelled with SIGTERM before SIGKILL (OpenJD's default,
    TERMINATE, kills at once, so the command cannot remove what it was writing)."""
    yaml = pytest.importorskip("yaml", reason="PyYAML comes with openjd-cli (requirements-dev.txt)")
    template = yaml.safe_load(TEMPLATE.read_text())
    actions = [step["script"]["actions"]["onRun"] for step in template["steps"]]
    assert [action.get("cancelation", {}).get("mode") for action in actions] == ["NOTIFY_THEN_TERMINATE"] * 2


HARNESS = """
const fs = require("fs");
const vm = require("vm");
const tasks = [];
const author = {
  Task: (name, type) => ({ name, type, commands: [], dependencies: [],
    addCommand(command) { this.commands.push(command); },
    addDependency(task) { this.dependencies.push(task.name); } }),
  Command: (type, parameters) => ({ type, parameters }),
};
const job = { settings: JSON.parse(process.argv[2]), addTask(task) { tasks.push(task); } };
const context = vm.createContext({ author, job, JSON, String });
vm.runInContext(fs.readFileSync(process.argv[1], "utf8") + "\\ncompileJob(job);", context);
console.log(JSON.stringify(tasks));
"""


def compile_flamenco_job(settings: dict) -> list[dict]:
    result = subprocess.run([NODE, "-e", HARNESS, str(JOB_TYPE), json.dumps(settings)], capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_flamenco_job_type_syntax():
    result = subprocess.run([NODE, "--check", str(JOB_TYPE)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_flamenco_job_runs_chunks_then_merge(job):
    folder, cache, topology, single = job
    (folder / "flamenco").mkdir()
    settings = dict(input_cache=str(cache), topology=str(topology), output_cache=str(folder / "flamenco.pc2"),
                    chunk_directory=str(folder / "flamenco"), step=4, speed=0.5, chunks=3, runner="python",
                    python=sys.executable, core_directory=str(ROOT),
                    extension_module="bl_ext.user_default.shape_differences")
    tasks = compile_flamenco_job(settings)
    assert [task["name"] for task in tasks] == ["retime-1-of-3", "retime-2-of-3", "retime-3-of-3", "merge"]
    assert tasks[-1]["dependencies"] == ["retime-1-of-3", "retime-2-of-3", "retime-3-of-3"]
    for task in tasks[:-1]:  # each chunk checks the merge's output before its in-betweens
        script = task["commands"][0]["parameters"]["args"][-1]  # the command's arguments as a JSON list
        assert json.dumps(["--merged-output", settings["output_cache"]], separators=(",", ":"))[1:-1] in script
    for task in tasks:  # what the workers would run, in dependency order
        (command,) = task["commands"]
        assert command["type"] == "exec"
        result = subprocess.run([command["parameters"]["exe"], *command["parameters"]["args"]],
                                capture_output=True, text=True, timeout=300)
        assert result.returncode == 0, result.stderr
    _same_frames(folder / "flamenco.pc2", single)

    shutil.rmtree(folder / "flamenco")  # another job's whole chunk set in the folder: the merge refuses it
    _other_jobs_chunks(cache, topology, folder / "flamenco", 3)
    (command,) = tasks[-1]["commands"]
    result = subprocess.run([command["parameters"]["exe"], *command["parameters"]["args"]],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 2 and "another job has written into the chunk folder" in result.stderr
    _same_frames(folder / "flamenco.pc2", single)

    without = subprocess.run([NODE, "-e", HARNESS, str(JOB_TYPE), json.dumps(dict(settings, core_directory=""))],
                             capture_output=True, text=True, timeout=60)
    assert without.returncode != 0 and "runner python needs core_directory" in without.stderr

    blender = compile_flamenco_job(dict(settings, runner="blender"))
    command = blender[0]["commands"][0]
    assert command["type"] == "blender-render" and command["parameters"]["exe"] == "{blender}"
    assert "bl_ext.user_default.shape_differences.core.__main__" in command["parameters"]["args"][1]


#: What `blender -b --python-exit-code CODE --python-expr SCRIPT` does with the runner "blender"'s
#: SCRIPT (argv[1]), for a plain Python: the extension is importable under its module name ("ext"),
#: an uncaught exception exits CODE, and sys.exit(code) exits with that code (Blender's bpy_atexit
#: closes Blender, then Python exits). With argv[2] "cancel" the task is cancelled with SIGTERM,
#: as a farm does, as its output is being written; with "fail" writing the output raises an
#: error the command does not expect.
BLENDER_PYTHON_EXPR = """
import os, signal, sys, types
extension = types.ModuleType("ext")
extension.__path__ = [{root!r}]
sys.modules["ext"] = extension
if sys.argv[2:] in (["cancel"], ["fail"]):
    import ext.core.point_cache as point_cache
    write = point_cache.write_atomically

    def cancelled(path, blocks, **options):
        if sys.argv[2] == "fail":
            raise ZeroDivisionError("a failure nobody expects")
        os.kill(os.getpid(), signal.SIGTERM)
        return write(path, blocks, **options)

    point_cache.write_atomically = cancelled
try:
    exec(sys.argv[1], {{"__name__": "__main__"}})
except Exception:
    import traceback
    traceback.print_exc()
    sys.exit({code})
"""


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_flamenco_blender_runner_exits_with_the_command_s_status(job, tmp_path):
    """The runner "blender"'s chunk task exits as the command does: 0 done, 2 refused, 143 when the
    farm cancels it with SIGTERM (it said 2, through a failed assert, so a cancelled task read as a
    failed one, with an AssertionError traceback in its log), the chunk file removed, and 1 on an
    unexpected failure, as the runner "python" (`python -m core`) does (it said 2, a refusal's
    status)."""
    folder, cache, topology, single = job
    settings = dict(input_cache=str(cache), topology=str(topology), output_cache=str(tmp_path / "out.pc2"),
                    chunk_directory=str(tmp_path), step=4, speed=0.5, chunks=2, runner="blender",
                    extension_module="ext")
    (command,) = compile_flamenco_job(settings)[0]["commands"]
    before = command["parameters"]["argsBefore"]
    assert before[0] == "--python-exit-code"
    script = command["parameters"]["args"][1]
    expr = BLENDER_PYTHON_EXPR.format(root=str(ROOT), code=int(before[1]))

    def run(script, *how):
        return subprocess.run([sys.executable, "-c", expr, script, *how], cwd=tmp_path, capture_output=True,
                              text=True, timeout=300)

    cancelled = run(script, "cancel")
    assert cancelled.returncode == 128 + 15, cancelled.stderr
    assert cancelled.stderr.splitlines()[-1] == "retime: cancelled (SIGTERM), nothing written"
    assert not (tmp_path / "chunk1.pc2").exists()
    failed = run(script, "fail")
    assert failed.returncode == 1, failed.stderr
    assert "retime: failed: " in failed.stderr and "ZeroDivisionError" in failed.stderr.splitlines()[-1]
    assert not (tmp_path / "chunk1.pc2").exists()
    refused = run(script.replace(str(topology), str(tmp_path / "missing.obj")))
    assert refused.returncode == 2 and "Traceback" not in refused.stderr, refused.stderr
    done = run(script)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "chunk1.pc2").exists()


@pytest.mark.skipif(OPENJD is None, reason="openjd-cli is not installed (requirements-dev.txt)")
def test_openjd_refuses_a_bad_output_before_any_chunk_is_computed(job, tmp_path):
    """An OutputCache the merge cannot write (under a file) or that is the job's input: the first
    chunk task refuses it before its in-betweens, naming it (before, every chunk was computed and
    only the Merge refused it); no chunk is written, the input is unchanged."""
    folder, cache, topology, single = job
    before = cache.read_bytes()
    for output, message in ((cache / "out.pc2", "is a file, not a folder"),
                            (cache, "is the input cache")):
        chunks = tmp_path / f"chunks_{len(message)}"
        chunks.mkdir()
        parameters = dict(InputCache=cache, Topology=topology, OutputCache=output, ChunkDirectory=chunks,
                          ExtensionDirectory=ROOT, Python=sys.executable, Step=4, Speed=0.5, Chunks=2)
        result = subprocess.run(_openjd_command(parameters), capture_output=True, text=True, timeout=600)
        log = result.stdout + result.stderr
        assert result.returncode != 0, log[-3000:]
        assert "--merged-output (the file the chunks will be merged into)" in log and message in log, log[-3000:]
        assert "retime: sample" not in log  # no in-between computed
        assert not list(chunks.iterdir())
    assert cache.read_bytes() == before


def test_a_chunk_checks_the_merged_output_first(job, capsys):
    """`retime --chunk I/N --merged-output PC2` refuses, with exit status 2 and no chunk written, a
    merged output that cannot be written, is the input, is the chunk itself or is not named .pc2;
    a good one changes nothing in the chunk; without --chunk/--gaps the option is refused."""
    folder, cache, topology, single = job
    settings = ["retime", str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5", "-q"]
    chunk = folder / "checked_chunk1.pc2"
    for merged, message in ((cache / "out.pc2", "is a file, not a folder"), (cache, "is the input cache"),
                            (chunk, "is this chunk's output (-o)"), (folder / "out", "is not named .pc2")):
        assert main([*settings, "--chunk", "1/2", "-o", str(chunk), "--merged-output", str(merged)]) == 2
        err = capsys.readouterr().err
        assert "--merged-output (the file the chunks will be merged into)" in err and message in err, err
        assert not chunk.exists()
    assert main([*settings, "-o", str(folder / "whole.pc2"), "--merged-output", str(folder / "out.pc2")]) == 2
    assert "--merged-output goes with --chunk I/N or --gaps A:B" in capsys.readouterr().err
    plain = folder / "plain_chunk1.pc2"
    assert main([*settings, "--chunk", "1/2", "-o", str(plain)]) == 0
    assert main([*settings, "--chunk", "1/2", "-o", str(chunk), "--merged-output", str(folder / "out.pc2")]) == 0
    assert chunk.read_bytes() == plain.read_bytes()
    assert not (folder / "out.pc2").exists()
