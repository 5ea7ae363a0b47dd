// cmd_run.cpp - `esim run SCENARIO`: the command line of a run (tools/app/run.h does it).
#include <memory>
#include <string>

#include "sim/core_error.h"
#include "sim/message_text.h"
#include "tools/app/run.h"
#include "tools/esim/command.h"

namespace esim::cli {
namespace {

// `esim run --help`'s account of the label files (README: Labels)
const char* const kLabelsHelp = R"(
Labels (--labels): DIR/labels/, one set per video frame, same camera and size, lossless:
  mask_NNNNN.png   8-bit class id per pixel: 0 background, 1 tool_shaft (insulated shaft,
                   handle), 2 tool_tip (bare metal), 3 tissue (intact), 4 coagulated
                   (coagulation >= 1-1/e: Arrhenius Omega >= 1), 5 desiccated (desiccation
                   >= 0.5; includes charred), 6 cut_wall (cutWall >= 0.5: faces exposed by
                   removal), 7 overlay (colour bar, time text). Priority where states meet:
                   desiccated > coagulated > cut_wall > tissue; thresholds per pixel on the
                   interpolated per-vertex fractions.
  depth_NNNNN.png  16-bit depth along the camera axis (OpenCV Z) x camera.json depth.unit_m;
                   0 = no surface, 65535 = at or beyond depth.far_m.
  frames.jsonl     per frame: time_s, tool pose (position_m, orientation_wxyz), tip_px,
                   generator_on, power_w, contact_nodes, class_pixels, state_pixels.
  camera.json      OpenCV intrinsics fx fy cx cy width height, world->camera R t, depth unit.
  classes.json     ids, names, preview colours, thresholds.   coco.json: tool and cut
                   instances per frame (uncompressed RLE).   preview.mp4: --labels preview.
  The labels are a second pass over the frame's own geometry, one sample per pixel centre;
  hashes.json gets mask_xxh3 and depth_xxh3 per frame.)";

Registrar reg(
    {"run"}, "Run a scenario: simulate, render, encode, report", [](CLI::App& app) -> Runner {
      auto opt = std::make_shared<app::RunOptions>();
      // required, checked by the runner: `--labels SCENARIO` takes the scenario as
      // the label mode (an option with an optional value), which the runner undoes
      app.add_option("scenario", opt->scenario,
                     "scenario YAML file (required; - reads standard input)");
      app.add_option("-o,--out", opt->outDir,
                     "output folder (default out/<name>); never a folder of other "
                     "files, an earlier run only with --overwrite");
      app.add_option("--frames", opt->frames, "number of frames (default: duration x fps)")
          ->check(CLI::Range(1, 100000000));
      app.add_option("--fields", opt->fieldsEvery,
                     "write every Nth frame's fields as VTU (0: none)")
          ->check(CLI::Range(0, 100000000));
      app.add_option("--set", opt->sets, "override a scenario field: key.path=value");
      app.add_flag("--no-video", opt->noVideo, "skip video encoding");
      app.add_flag("--overwrite", opt->overwrite,
                   "replace an earlier ESim run in the output folder");
      app.add_flag("-q,--quiet", opt->quiet, "no progress output");
      app.add_flag("--no-memory-guard", opt->noMemoryGuard,
                   "run on when the memory left runs short (by default the electric column "
                   "cache gives memory back, then the run stops with its reports, exit 1, "
                   "before the kernel would kill it without them)");
      app.add_flag("--no-draw-thread{false}", opt->drawOnThread,
                   "draw each frame after its physics, in the frame loop (by default frame k "
                   "is drawn on a thread of its own while frame k+1 is simulated: the same "
                   "images, a frame period closer to the slower of the two)");
      app.add_flag("--physics-first", opt->physicsFirst,
                   "draw only on CPU the physics does not want: the drawing thread and "
                   "llvmpipe's rasterizer threads in Linux's SCHED_IDLE class (the same "
                   "images; on a machine shared with other work the video then waits for "
                   "idle CPU: for interactive runs, not for batches)");
      app.add_flag("--plots", opt->plots,
                   "also write timing.png (stage times per frame, power, temperature, removed "
                   "tets; needs python3-matplotlib, else a warning)");
      auto labelsMode = std::make_shared<std::string>();
      CLI::Option* labels = app.add_option("--labels", *labelsMode,
                                           "per-frame labels in DIR/labels/ (see below); '--labels "
                                           "preview' also writes labels/preview.mp4")
                                ->expected(0, 1);
      app.footer(kLabelsHelp);
      return [opt, labels, labelsMode] {
        if (opt->scenario.empty() && labels->count() > 0 && *labelsMode != "preview") {
          opt->scenario = *labelsMode;  // `esim run --labels SCENARIO ...`
          labelsMode->clear();
        }
        ESIM_VERIFY(!opt->scenario.empty(),
                    "scenario is required: esim run SCENARIO [options] (--help)");
        if (labels->count() > 0) {
          ESIM_VERIFY(labelsMode->empty() || *labelsMode == "preview",
                      "--labels: " + quoteInMessage(*labelsMode) +
                          " is unknown, expected nothing or 'preview'");
          opt->labels = true;
          opt->labelsPreview = *labelsMode == "preview";
        }
        return app::runScenario(*opt);
      };
    });

}  // namespace
}  // namespace esim::cli
