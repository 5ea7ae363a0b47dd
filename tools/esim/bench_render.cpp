// bench_render.cpp - `esim bench render`: per-frame render, conversion and encode times.
//
// 1. Surfaces (--surfaces): "slab" (makeSlab, 1013 nodes, boundary faces), "slab20k"
//    (71 x 71 x 3 nodes: 20,720 triangles), "sphere20k" (icosphere, 20,480
//    triangles), "liver" (assets/liver.obj). The analytic cut (render_scenes.h) gives
//    every frame a moving hot trail, so frames differ like a real run's.
// 2. For each surface and size (--sizes): render --frames frames after --warmup
//    frames, timing render() (upload, draw, MSAA resolve, read-back, overlay).
// 3. Feed the frames to VideoEncoder (libx264, --preset/--crf, reproducible: one
//    thread) and report its RGB->YUV conversion and encode times per frame. Frames
//    are encoded after rendering so the two do not compete for the cores here.
// 4. Print a table; --csv writes surface,width,height,triangles,render_ms,convert_ms,
//    encode_ms (medians for render, means for convert/encode). The table also splits
//    render() into CPU preparation, drawing, resolve + read-back and overlay, and gives
//    the process CPU time per frame (all llvmpipe threads): on a shared machine the
//    wall time of a 2-thread rasteriser depends on the load, the CPU time much less.
// --labels: after each render(), Renderer::renderLabels() (the label pass, labels.h) is timed
// apart: labels_ms (median wall) and labels_cpu (process CPU per frame) end each line.
// A benchmark, never a pass/fail test. Target: render + read-back < 10 ms at
// 1280x720 for ~20k triangles.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <limits>
#include <memory>
#include <sstream>

#include "render/image_hash.h"
#include "render/renderer.h"
#include "render/video_encoder.h"
#include "sim/core_error.h"
#include "sim/message_text.h"
#include "tools/app/bench_common.h"
#include "tools/app/render_scenes.h"
#include "tools/esim/command.h"

namespace esim::cli {
using namespace ::esim::app;
namespace {

struct BenchRenderOptions {
  std::string surfaces = "slab,slab20k,sphere20k,liver";
  std::string sizes = "640x480,1280x720";
  int frames = 30;
  int warmup = 3;
  std::string look = "temperature";
  std::string backend = "osmesa";
  std::string msaa = "0,4";
  std::string shading = "pixel,vertex";
  std::string preset = "veryfast";
  int crf = 20;
  std::string liver = "assets/liver.obj";
  std::string csv;
  bool labels = false;  // also time the label pass
};

SurfaceSnapshot makeSurface(const std::string& name, const std::string& liverPath,
                            AnalyticCut& cut) {
  if (name == "slab" || name == "slab20k") {
    SlabSpec spec;
    if (name == "slab20k") spec.nodesPerAxis = {71, 71, 3};
    cut.topZM = spec.sizeM.z();
    return slabSurface(spec);
  }
  if (name == "sphere20k") {
    cut.topZM = 0.01;  // sphere of radius 10 mm centred at z = 0: the cut runs over its top
    return icosphereSurface(0.01, 5, {0, 0, 0});
  }
  if (name == "liver") {
    SurfaceSnapshot s = fileSurface(liverPath);
    float zMax = -1e9f;
    for (int v = 0; v < s.numVertices(); ++v) zMax = std::max(zMax, s.positionsM[3 * v + 2]);
    cut.topZM = zMax;
    return s;
  }
  throw Error("--surfaces: unknown surface " + quoteInMessage(name) +
              ", expected slab, slab20k, sphere20k or liver");
}

// CPU time of the whole process (all llvmpipe threads) [ms]
double processCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// a renderer variant: lighting and MSAA samples
struct Variant {
  std::string shading;
  int msaa;
};

// every shading x every MSAA; the best (pixel, most samples) first, as the reference of
// the others' PSNR
std::vector<Variant> parseVariants(const BenchRenderOptions& opt) {
  std::vector<Variant> variants;
  std::vector<int> msaaList;
  for (const std::string& m : splitList(opt.msaa)) {
    ESIM_VERIFY(
        m == "0" || m == "2" || m == "4",
        "--msaa: " + quoteInMessage(m) + " is not a sample count, expected 0, 2 or 4 (comma list)");
    msaaList.push_back(std::stoi(m));
  }
  std::sort(msaaList.rbegin(), msaaList.rend());
  std::vector<std::string> shadings = splitList(opt.shading);
  for (const std::string& sh : shadings)
    ESIM_VERIFY(
        sh == "pixel" || sh == "vertex",
        "--shading: " + quoteInMessage(sh) + " is unknown, expected pixel or vertex (comma list)");
  std::sort(shadings.begin(), shadings.end());  // "pixel" before "vertex"
  for (const std::string& sh : shadings)
    for (int m : msaaList) variants.push_back({sh, m});
  ESIM_VERIFY(!variants.empty(), "--msaa and --shading need at least one value each");
  return variants;
}

// the timed frames of one variant (the cut advances 0.5 mm per frame)
struct RenderedFrames {
  std::vector<std::vector<std::uint8_t>> frames;
  std::vector<double> renderMs;
  RenderTimings split;           // means over the timed frames
  double cpuMs = 0;              // process CPU time in render() per timed frame
  std::vector<double> labelsMs;  // renderLabels() per timed frame (--labels)
  double labelsCpuMs = 0;        // its process CPU time per timed frame
};

RenderedFrames renderFrames(Renderer& renderer, const SurfaceSnapshot& base, const AnalyticCut& cut,
                            const BenchRenderOptions& opt) {
  using Clock = std::chrono::steady_clock;
  RenderedFrames out;
  for (int f = -opt.warmup; f < opt.frames; ++f) {
    SurfaceSnapshot snap = base;
    AnalyticCut c = cut;
    c.tipXM = -0.02 + 0.0005 * (f + opt.warmup);
    applyAnalyticCut(c, (f + opt.warmup) / 30.0, snap);
    const auto t0 = Clock::now();
    const double cpu0 = processCpuMs();
    const auto& rgb = renderer.render(snap);
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    if (f < 0) continue;
    out.cpuMs += (processCpuMs() - cpu0) / opt.frames;
    const RenderTimings& t = renderer.lastTimings();
    out.split.prepareMs += t.prepareMs / opt.frames;
    out.split.drawMs += t.drawMs / opt.frames;
    out.split.readbackMs += t.readbackMs / opt.frames;
    out.split.overlayMs += t.overlayMs / opt.frames;
    out.renderMs.push_back(ms);
    out.frames.push_back(rgb);
    if (opt.labels) {
      const auto t1 = Clock::now();
      const double cpu1 = processCpuMs();
      renderer.renderLabels();
      out.labelsMs.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t1).count());
      out.labelsCpuMs += (processCpuMs() - cpu1) / opt.frames;
    }
  }
  return out;
}

// mean PSNR of the frames against the reference's (identical frames count as 99 dB; all
// identical: inf) and the largest share of pixels off by more than the threshold
void compareFrames(const std::vector<std::vector<std::uint8_t>>& reference,
                   const std::vector<std::vector<std::uint8_t>>& frames, int w, int h,
                   double* psnrDb, double* offShare) {
  double sum = 0;
  bool allIdentical = true;
  for (size_t f = 0; f < frames.size(); ++f) {
    const ImageComparison c = compareImages(reference[f], frames[f], w, h);
    *offShare = std::max(*offShare, c.offShare);
    if (std::isfinite(c.psnrDb)) {
      sum += c.psnrDb;
      allIdentical = false;
    } else {
      sum += 99.0;
    }
  }
  if (!allIdentical) *psnrDb = sum / static_cast<double>(frames.size());
}

// RGB->YUV and x264 time per frame [ms] (frames are moved into the encoder)
void encodeFrames(std::vector<std::vector<std::uint8_t>>& frames, int w, int h,
                  const BenchRenderOptions& opt, double* convertMs, double* encodeMs) {
  if (w % 2 != 0 || h % 2 != 0) return;
  const std::string tmpVideo =
      (std::filesystem::temp_directory_path() / "esim_bench_render.mp4").string();
  VideoEncoder enc;
  VideoEncoder::Options vo;
  vo.path = tmpVideo;
  vo.width = w;
  vo.height = h;
  vo.preset = opt.preset;
  vo.crf = opt.crf;
  enc.open(vo);
  for (auto& f : frames) enc.push(std::move(f));
  enc.close();
  *convertMs = 1e3 * enc.convertSeconds() / opt.frames;
  *encodeMs = 1e3 * enc.encodeSeconds() / opt.frames;
  std::filesystem::remove(tmpVideo);
}

int benchRender(const BenchRenderOptions& opt) {
  ESIM_VERIFY(opt.frames >= 1 && opt.warmup >= 0, "--frames must be >= 1, --warmup >= 0");
  std::vector<std::array<int, 2>> sizes;
  for (const std::string& s : splitList(opt.sizes)) {
    int w = 0, h = 0, used = 0;  // (all of it: "1280x720x3" was taken as 1280x720)
    ESIM_VERIFY(
        std::sscanf(s.c_str(), "%dx%d%n", &w, &h, &used) == 2 && used == static_cast<int>(s.size()),
        "--sizes: " + quoteInMessage(s) + " is not WIDTHxHEIGHT (e.g. 1280x720)");
    ESIM_VERIFY(w >= 16 && w <= 8192 && h >= 16 && h <= 8192,
                "--sizes: " + quoteInMessage(s) +
                    " is out of range, expected 16..8192 pixels each (the renderer's)");
    sizes.push_back({w, h});
  }
  ESIM_VERIFY(!sizes.empty(), "--sizes is empty (expected e.g. 640x480,1280x720)");
  const std::vector<std::string> surfaces = splitList(opt.surfaces);
  ESIM_VERIFY(!surfaces.empty(),
              "--surfaces is empty, expected slab, slab20k, sphere20k or liver (comma list)");
  const std::vector<Variant> variants = parseVariants(opt);
  app::CsvOutput csv(opt.csv,
                     std::string("surface,width,height,triangles,render_ms,convert_ms,encode_ms,"
                                 "shading,msaa,psnr_db") +
                         (opt.labels ? ",labels_ms" : ""));
  const char* lpThreads = std::getenv("LP_NUM_THREADS");
  bool header = false;

  // 1. the surfaces, all made before the first is drawn (an unknown name, or a liver file
  // that cannot be read, stops the bench before anything runs)
  std::vector<AnalyticCut> cuts(surfaces.size());
  std::vector<SurfaceSnapshot> bases;
  for (size_t k = 0; k < surfaces.size(); ++k)
    bases.push_back(makeSurface(surfaces[k], opt.liver, cuts[k]));
  for (size_t k = 0; k < surfaces.size(); ++k) {
    const std::string& name = surfaces[k];
    const AnalyticCut& cut = cuts[k];
    const SurfaceSnapshot& base = bases[k];
    for (const auto& [w, h] : sizes) {
      std::vector<std::vector<std::uint8_t>> reference;  // frames of the first variant
      for (size_t vi = 0; vi < variants.size(); ++vi) {
        const Variant& variant = variants[vi];
        RenderOptions ro;
        ro.width = w;
        ro.height = h;
        ro.look = opt.look;
        ro.backend = opt.backend;
        ro.msaaSamples = variant.msaa;
        ro.shading = variant.shading;
        ro.eyeM = {0.0f, -0.06f, static_cast<float>(cut.topZM) + 0.05f};
        ro.targetM = {0.0f, 0.0f, static_cast<float>(cut.topZM) - 0.004f};
        Renderer renderer(ro);
        if (!header) {
          std::printf(
              "esim bench render: %s look, backend %s, %d frames (+%d warm-up), "
              "x264 preset %s crf %d (1 thread)\nGL: %s | %s; LP_NUM_THREADS=%s; %s\n",
              opt.look.c_str(), renderer.glPlatform().c_str(), opt.frames, opt.warmup,
              opt.preset.c_str(), opt.crf, renderer.glRenderer().c_str(),
              renderer.glVersion().c_str(), lpThreads ? lpThreads : "(unset)",
              VideoEncoder::libraryVersions().c_str());
          if (variants.size() > 1)
            std::printf(
                "psnr_db: mean PSNR of each frame against the same frame of the first "
                "variant (%s shading, MSAA %d), inf = identical; off_%%: largest share of "
                "pixels off by more than %d\n",
                variants[0].shading.c_str(), variants[0].msaa, kPixelDiffThreshold);
          std::printf(
              "%-10s %6s %6s %9s %7s %4s %10s %10s %10s %7s %6s %10s %10s | means: %7s %7s "
              "%7s %7s %7s%s\n",
              "surface", "width", "height", "triangles", "shading", "msaa", "render_ms",
              "render_p95", "render_max", "psnr_db", "off_%", "convert_ms", "encode_ms", "prep",
              "draw", "read", "overlay", "cpu_ms", opt.labels ? " | labels_ms labels_cpu" : "");
          header = true;
        }
        // 2. render; 3. image quality against the first variant's frames; 4. encode
        RenderedFrames r = renderFrames(renderer, base, cut, opt);
        std::vector<double>& renderMs = r.renderMs;
        const RenderTimings& split = r.split;
        const double cpuMs = r.cpuMs;
        double psnrDb = std::numeric_limits<double>::infinity(), offShare = 0;
        if (vi == 0)
          reference = r.frames;
        else
          compareFrames(reference, r.frames, w, h, &psnrDb, &offShare);
        double convertMs = 0, encodeMs = 0;
        encodeFrames(r.frames, w, h, opt, &convertMs, &encodeMs);
        // 5. report
        std::vector<double> sorted = renderMs;
        std::sort(sorted.begin(), sorted.end());
        const double p95 =
            sorted[std::min(sorted.size() - 1, static_cast<size_t>(0.95 * sorted.size()))];
        std::printf(
            "%-10s %6d %6d %9d %7s %4d %10.2f %10.2f %10.2f %7.2f %6.2f %10.2f %10.2f | "
            "%14.2f %7.2f %7.2f %7.2f %7.2f",
            name.c_str(), w, h, base.numTriangles(), variant.shading.c_str(), variant.msaa,
            median(renderMs), p95, sorted.back(), psnrDb, 100 * offShare, convertMs, encodeMs,
            split.prepareMs, split.drawMs, split.readbackMs, split.overlayMs, cpuMs);
        if (opt.labels) std::printf(" | %9.2f %10.2f", median(r.labelsMs), r.labelsCpuMs);
        std::printf("\n");
        std::fflush(stdout);
        if (csv)
          csv.out() << name << "," << w << "," << h << "," << base.numTriangles() << ","
                    << median(renderMs) << "," << convertMs << "," << encodeMs << ","
                    << variant.shading << "," << variant.msaa << "," << psnrDb;
        if (csv && opt.labels) csv.out() << "," << median(r.labelsMs);
        if (csv) csv.out() << "\n";
      }
    }
  }
  if (csv) {
    csv.commit();
    std::printf("wrote %s\n", printablePath(opt.csv).c_str());
  }
  return kExitOk;
}

Registrar registerBenchRender(
    {"bench", "render"}, "Renderer benchmark: render+read-back, RGB->YUV and encode ms per frame",
    [](CLI::App& app) -> Runner {
      auto opt = std::make_shared<BenchRenderOptions>();
      app.add_option("--surfaces", opt->surfaces, "slab, slab20k, sphere20k, liver (comma list)")
          ->capture_default_str();
      app.add_option("--sizes", opt->sizes, "frame sizes WxH, comma separated")
          ->capture_default_str();
      app.add_option("--frames", opt->frames, "timed frames per case")->capture_default_str();
      app.add_option("--warmup", opt->warmup, "untimed frames first")->capture_default_str();
      app.add_option("--look", opt->look, "temperature or tissue")->capture_default_str();
      app.add_option("--backend", opt->backend, "osmesa or egl")->capture_default_str();
      app.add_option("--msaa", opt->msaa, "MSAA samples, comma list of 0, 2, 4")
          ->capture_default_str();
      app.add_option("--shading", opt->shading, "lighting, comma list of 'pixel', 'vertex'")
          ->capture_default_str();
      // checked here, not when the encoder opens (after the first surface's rows)
      app.add_option("--preset", opt->preset, "x264 preset")
          ->check(CLI::IsMember({"ultrafast", "superfast", "veryfast", "faster", "fast", "medium",
                                 "slow", "slower", "veryslow"}))
          ->capture_default_str();
      app.add_option("--crf", opt->crf, "x264 CRF")
          ->check(CLI::Range(0, 51))
          ->capture_default_str();
      const CLI::Option* liver =
          app.add_option("--liver", opt->liver, "surface file of the 'liver' case")
              ->capture_default_str();
      app.add_flag("--labels", opt->labels,
                   "also time the label pass (Renderer::renderLabels) after each frame");
      app.add_option("--csv", opt->csv,
                     "write surface,width,height,triangles,render_ms,convert_ms,encode_ms,"
                     "shading,msaa,psnr_db");
      return [opt, liver] {
        const std::vector<std::string> surfaces = splitList(opt->surfaces);
        if (std::find(surfaces.begin(), surfaces.end(), "liver") == surfaces.end())
          refuseGiven({liver}, "bench render",
                      "is the 'liver' case's, which --surfaces leaves out");
        return benchRender(*opt);
      };
    });

}  // namespace
}  // namespace esim::cli
