// run.h - one run of a scenario: simulate, render, encode, report (`esim run`).
//
// 1. Load and check the scenario (+ --set overrides); check the output folder.
// 2. Build the mesh and the phases the scene lists; open the renderer.
// 3. Create DIR.partial/; open the video.
// 4. Frame loop: physics stages -> snapshot -> render (+ label pass) -> encoder / PNG /
//    hashes / VTU / label files.
// 5. Close the video; write timing.csv, timing.json, trace.json, hashes.json,
//    scenario.yaml, (--plots) timing.png, summary.txt; rename DIR.partial/ to DIR/.
// Errors (sim/core_error.h): bad input (steps 1-3) is thrown with nothing left on disk; a
// run error in the frame loop (a failed solve, all tissue removed) and an interruption
// (SIGINT, SIGTERM) stop the loop, write the reports of the frames done, marked
// "complete": false, keep DIR.partial/ and return exit code 1.
#pragma once

#include <string>
#include <vector>

namespace esim::app {

struct RunOptions {
  std::string scenario;           // scenario YAML file
  std::string outDir;             // "" = out/<name>
  int frames = 0;                 // 0: from the scenario
  int fieldsEvery = -1;           // -1: from the scenario
  std::vector<std::string> sets;  // key.path=value overrides
  bool noVideo = false;
  bool quiet = false;
  bool overwrite = false;      // replace an earlier ESim run in outDir
  bool labels = false;         // per-frame labels in DIR/labels/ (run_labels.h)
  bool labelsPreview = false;  // and labels/preview.mp4
  bool plots = false;  // also write timing.png (tools/plot_timing.py; a warning if it cannot)
  // false: between frames, give the electric column cache back and then stop (exit 1,
  // reports written) when the memory left runs under the run's reserve (memory_room.h
  // MemoryGuard); true: run on, at the risk of the kernel's kill without reports
  bool noMemoryGuard = false;
  // draw frame f on a thread of its own while frame f+1 is simulated (the same images;
  // false: draw each frame after its physics, in the loop)
  bool drawOnThread = true;
  // the drawing thread and llvmpipe's rasterizer threads at SCHED_IDLE (thread_priority.h):
  // the physics never waits for the renderer's CPU; on a machine shared with other work the
  // frames are drawn only on CPU nothing else wants
  bool physicsFirst = false;
};

// runs the scenario; returns the exit code (0 complete, 1 failed or interrupted, outputs
// kept in DIR.partial/); throws Error for bad input, before anything is written
int runScenario(const RunOptions& options);

// asks the frame loop to stop after the current frame (signal-safe)
void requestStop();

}  // namespace esim::app
