// cmd_render_sample.cpp - `esim render-sample`: still images of the analytic slab cut.
//
// 1. Build a fine slab surface (0.5 mm top spacing) and apply the analytic cut
//    (render_scenes.h): a hot trail along y = 0 behind a blade at x = 10 mm.
// 2. Render it in the temperature and tissue looks.
// 3. Write <out>/sample_temperature.png and <out>/sample_tissue.png and print the
//    GL strings and frame hashes.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "render/image_hash.h"
#include "render/image_png.h"
#include "render/renderer.h"
#include "sim/core_error.h"
#include "sim/message_text.h"
#include "tools/app/render_scenes.h"
#include "tools/app/run_output.h"
#include "tools/esim/command.h"

namespace esim::cli {
using namespace ::esim::app;
namespace {

struct RenderSampleOptions {
  std::string out = "docs";
  int width = 640, height = 360;
  std::string backend = "osmesa";
  std::string surface = "slab";  // or a closed surface file, e.g. assets/liver.obj
};

int runRenderSample(const RenderSampleOptions& opt) {
  // 1. scene
  SurfaceSnapshot snap;
  AnalyticCut cut;
  std::array<float, 3> eye{-0.004f, -0.062f, 0.058f}, target{-0.008f, 0.0f, 0.006f};
  if (opt.surface == "slab") {
    SlabSpec spec;
    spec.nodesPerAxis = {201, 201, 2};
    snap = slabSurface(spec);
  } else {
    // a surface file: the hot trail runs over its highest point along x
    snap = fileSurface(opt.surface);
    float zMax = -1e9f;
    for (int v = 0; v < snap.numVertices(); ++v) zMax = std::max(zMax, snap.positionsM[3 * v + 2]);
    cut.topZM = zMax;
    eye = {0.0f, -0.16f, zMax + 0.10f};
    target = {0.0f, 0.0f, zMax - 0.03f};
  }
  applyAnalyticCut(cut, 9.0, snap);
  const auto options = [&](const std::string& look) {
    RenderOptions ro;
    ro.width = opt.width;
    ro.height = opt.height;
    ro.look = look;
    ro.backend = opt.backend;
    ro.eyeM = eye;
    ro.targetM = target;
    ro.fovDeg = 32;
    return ro;
  };
  validateRenderOptions(options("tissue"));  // before the folder is made: nothing left behind
  app::FolderLock outLock;
  app::createOutputFolder(opt.out, "--out", outLock);
  // 2-3. both looks
  for (const std::string look : {"temperature", "tissue"}) {
    const RenderOptions ro = options(look);
    Renderer renderer(ro);
    const auto& rgb = renderer.render(snap);
    const std::string path = opt.out + "/sample_" + look + ".png";
    writePng(path, rgb, ro.width, ro.height);
    std::printf("%s: %dx%d, %d triangles, xxh3 %s, GL %s | %s\n", printablePath(path).c_str(),
                ro.width, ro.height, snap.numTriangles(), hashToHex(hashFrame(rgb)).c_str(),
                renderer.glRenderer().c_str(), renderer.glVersion().c_str());
  }
  return kExitOk;
}

Registrar registerRenderSample(
    {"render-sample"}, "Render still PNGs of an analytic cut on the slab in both looks",
    [](CLI::App& app) -> Runner {
      auto opt = std::make_shared<RenderSampleOptions>();
      app.add_option("--out", opt->out, "output folder")->capture_default_str();
      // checked by the parser, named as the options (the renderer's own messages named
      // look.width/height and RenderOptions::backend, fields the user never wrote)
      app.add_option("--width", opt->width, "image width [px]")
          ->check(CLI::Range(16, 8192))
          ->capture_default_str();
      app.add_option("--height", opt->height, "image height [px]")
          ->check(CLI::Range(16, 8192))
          ->capture_default_str();
      app.add_option("--backend", opt->backend, "osmesa or egl")
          ->check(CLI::IsMember({"osmesa", "egl"}))
          ->capture_default_str();
      app.add_option("--surface", opt->surface, "'slab' or a closed surface file")
          ->capture_default_str();
      return [opt] { return runRenderSample(*opt); };
    });

}  // namespace
}  // namespace esim::cli
