// SPDX-License-Identifier: GPL-3.0-or-later
// Flamenco job type: retime a point cache with Shape Differences, split into chunks of key gaps
// that run on different workers, then merged into one PC2 (bit for bit what one process writes).
//
// Install: copy this file into the `scripts/` folder next to the Flamenco Manager executable and
// restart the Manager. Each chunk task runs the extension's headless command
// (`python -m core retime ... --chunk I/N`), either inside `blender -b` (runner "blender": the
// Shape Differences extension installed in the workers' Blender, whose bundled SciPy it uses) or
// with a plain Python that has NumPy and SciPy (runner "python": point `core_directory` at the
// extension's folder). A last task merges the chunks.

const JOB_TYPE = {
  label: "Shape Differences Retime",
  description: "Retime a PC2/MDD point cache from every n-th frame, in chunks on several workers",
  settings: [
    { key: "input_cache", type: "string", subtype: "file_path", required: true,
      description: "PC2 or MDD cache to retime" },
    { key: "topology", type: "string", subtype: "file_path", required: true,
      description: "OBJ with the mesh's faces (same vertices, same order as the cache)" },
    { key: "output_cache", type: "string", subtype: "file_path", required: true,
      description: "PC2 file to write" },
    { key: "chunk_directory", type: "string", subtype: "dir_path", required: true,
      description: "Folder every worker sees, for the chunk files and their stamps (one folder per job)" },
    { key: "step", type: "int32", default: 4, required: true,
      description: "Key every step-th sample of the input" },
    { key: "speed", type: "float", default: 0.5, required: true,
      description: "0.5 = twice as slow, 1 = original timing with dropped samples rebuilt, 2 = twice as fast" },
    { key: "chunks", type: "int32", default: 4, required: true,
      description: "Number of chunk tasks" },
    { key: "runner", type: "string", choices: ["blender", "python"], default: "blender", required: true,
      description: "Run each chunk in 'blender -b' (the installed extension) or a plain Python" },
    { key: "extension_module", type: "string", default: "bl_ext.user_default.shape_differences",
      description: "Runner blender: the extension's module name in the workers' Blender" },
    { key: "python", type: "string", default: "python3",
      description: "Runner python: the interpreter (NumPy and SciPy installed)" },
    { key: "core_directory", type: "string", subtype: "dir_path", default: "",
      description: "Runner python: the folder that holds the extension's core/ package" },
  ],
};

function compileJob(job) {
  const settings = job.settings;
  const chunks = settings.chunks;
  if (!(chunks >= 1)) {
    throw "chunks must be at least 1";
  }
  if (settings.runner === "python" && !settings.core_directory) {
    throw "runner python needs core_directory: the folder that holds the extension's core/ package";
  }
  const chunkFile = (index) => settings.chunk_directory + "/chunk" + index + ".pc2";
  // What the retime computes from its input: the chunks take it, and the merge too, which refuses
  // chunks of any other retime (another job's, written into the same chunk folder).
  const retimeSettings = [
    "--topology", settings.topology,
    "--step", String(settings.step),
    "--speed", String(settings.speed),
  ];

  const chunkTasks = [];
  for (let index = 1; index <= chunks; index++) {
    const task = author.Task("retime-" + index + "-of-" + chunks, "misc");
    task.addCommand(coreCommand(settings, [
      "retime", settings.input_cache, ...retimeSettings,
      "--chunk", index + "/" + chunks,
      "-o", chunkFile(index),
      // the merge's output, checked before the in-betweens: a path it cannot write fails every chunk at once
      "--merged-output", settings.output_cache,
    ]));
    job.addTask(task);
    chunkTasks.push(task);
  }

  const merge = author.Task("merge", "file-management");
  merge.addCommand(coreCommand(settings, [
    "merge", "--numbered", settings.chunk_directory + "/chunk#.pc2",
    "--count", String(chunks), "-o", settings.output_cache,
    "--retime", settings.input_cache, ...retimeSettings,
  ]));
  for (const task of chunkTasks) {
    merge.addDependency(task);
  }
  job.addTask(merge);
}

// A command that runs `python -m core <args>` through the chosen runner and exits with the command's
// status (0 done, 1 an unexpected failure, 2 refused, 143 cancelled with SIGTERM, 130 interrupted:
// docs/pipeline.md). In Blender, sys.exit ends Blender with that status; --python-exit-code 1 gives
// an uncaught exception (an unexpected failure, or the extension not installed) the status 1 that
// the runner "python" exits with.
function coreCommand(settings, args) {
  const run = "sys.exit(main(" + JSON.stringify(args) + "))";
  if (settings.runner === "python") {
    const script = "import sys; sys.path.insert(0, " + JSON.stringify(settings.core_directory) + "); " +
      "from core.__main__ import main; " + run;
    return author.Command("exec", { exe: settings.python, args: ["-c", script] });
  }
  const script = "import importlib, sys; " +
    "main = importlib.import_module(" + JSON.stringify(settings.extension_module + ".core.__main__") + ").main; " +
    run;
  return author.Command("blender-render", {
    exe: "{blender}",
    exeArgs: "{blenderArgs}",
    argsBefore: ["--python-exit-code", "1"],
    args: ["--python-expr", script],
  });
}
