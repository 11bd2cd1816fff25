// Flamenco job type: the Keyframe Implicit bake, its stages as tasks.
//
// Put this file in the `scripts` folder beside flamenco-manager. Every task runs the
// worker's Blender on the scene with the add-on enabled and runs one stage of
// `python -m keyframe_implicit farm` inside it (the add-on's farm command line):
//
//   prepare -> maps (a task per pairs_per_task keyframe pairs) -> paths
//   -> segment (a task per segment) -> assemble
//
// The job directory must be on storage every worker sees. Untested on a real Flamenco
// (none runs where the add-on is developed): the tests compile a job with a stand-in for
// Flamenco's `author` API and check the task graph.

const JOB_TYPE = {
  label: "Keyframe Implicit Bake",
  description: "Fill the frames between implicit keyframes, one task per keyframe pair",
  settings: [
    { key: "blendfile", type: "string", subtype: "file_path", required: true,
      description: "The scene to bake", visible: "web" },
    { key: "job_dir", type: "string", subtype: "dir_path", required: true,
      eval: "bpy.path.abspath('//') + bpy.path.display_name_from_filepath(bpy.data.filepath) + '_farm'",
      description: "Where the stages keep their files (shared storage)" },
    { key: "output_file", type: "string", subtype: "file_path", required: true,
      eval: "bpy.path.abspath('//') + bpy.path.display_name_from_filepath(bpy.data.filepath) + '_baked.blend'",
      description: "The baked .blend" },
    { key: "resolution", type: "int32", required: true, default: 48,
      eval: "C.scene.keyframe_implicit.resolution",
      description: "Grid cells along the keyframes' longest side" },
    { key: "pairs_per_task", type: "int32", required: true, default: 3,
      description: "Keyframe pairs whose maps one task solves, sharing the worker's cores" },
    { key: "segments", type: "int32", required: true,
      eval: "len(C.scene.keyframe_implicit.keyframes) - 1", visible: "hidden",
      description: "Keyframe pairs in the scene: one maps task and one segment task each" },
  ],
};

// Runs the add-on's farm command line inside the Blender that opened the .blend.
const RUN_FARM =
  "import sys; name = next(n for n in sorted(sys.modules) " +
  "if n.split('.')[-1] == 'keyframe_implicit'); " +
  "main = __import__(name + '.__main__', fromlist=['main']).main; " +
  "sys.exit(main(sys.argv[sys.argv.index('--') + 1:]))";

function compileJob(job) {
  const settings = job.settings;
  if (!(settings.segments >= 1)) {
    throw "segments must be at least 1: the scene needs two keyframes or more";
  }

  function stage(name, args) {
    const task = author.Task(name, "blender");
    task.addCommand(author.Command("blender-render", {
      exe: "{blender}",
      exeArgs: "{blenderArgs}",
      argsBefore: ["-b"],
      blendfile: settings.blendfile,
      args: ["--python-expr", RUN_FARM, "--", "farm"].concat(args),
    }));
    job.addTask(task);
    return task;
  }

  function after(tasks, task) {
    for (const t of tasks) task.addDependency(t);
    return task;
  }

  const dir = settings.job_dir;
  const prepare = stage("prepare", ["prepare", settings.blendfile, dir,
    "--resolution", String(settings.resolution), "--segments", String(settings.segments)]);
  const chunk = Math.max(1, settings.pairs_per_task || 1);
  const maps = [];
  for (let i = 1; i <= settings.segments; i += chunk) {
    const last = Math.min(i + chunk - 1, settings.segments);
    const pairs = last > i ? `${i}-${last}` : String(i);
    maps.push(after([prepare], stage(`maps-${pairs}`, ["maps", dir, "--pair", pairs])));
  }
  const paths = after(maps, stage("paths", ["paths", dir]));
  const segments = [];
  for (let i = 1; i <= settings.segments; i++) {
    segments.push(after([paths], stage(`segment-${i}`,
      ["segment", dir, "--segment", String(i)])));
  }
  after(segments, stage("assemble", ["assemble", dir, "--out", settings.output_file,
    "--scene", settings.blendfile]));
}
