// sweep_spec.h - a sweep file (`esim sweep SPEC`): a base scenario and the knobs to vary,
// expanded deterministically into variants, each a checked scenario.
//
//   name: slab_cut_8                  # default: the file's stem
//   base: ../slab_cut.yaml            # the scenario varied (relative to this file)
//   seed: 14                          # the random draws' seed (default 0)
//   draws: 4                          # random draws per grid point (default 1)
//   set:    {time.duration_s: 1.0}    # the same for every variant
//   grid:   {tool.voltage_v: [150, 250]}             # every combination, first key slowest
//   random: {camera.eye_m: {jitter: [0.004, 0.004, 0.002]},
//            path.angle_deg: {uniform: [-8, 8]}}
//   run_options: [--labels]           # passed to every `esim run`
//
// Keys are scenario key paths as `--set` takes them (docs/scenario-reference.md), plus
// three transforms of the tool path that no single key holds:
//   path.offset_m   [dx, dy, dz] added to every keyframe's position;
//   path.angle_deg  the path turned about the vertical through its centre (the middle of
//                   its first and last positions), the tool turned with it (orientation rz);
//   path.speed      the tool's speed as a factor (keyframe times divided by it);
// the planned cut (mesh.slab.grading, mesh.file.refine from_m/to_m) moves with the path,
// so the fine zone of the mesh follows the tool.
// Random draws: {uniform: [lo, hi]} (numbers, or [x, y, z] lists component-wise),
// {integer: [lo, hi]} (inclusive), {choice: [a, b, ...]} (any values) and {jitter: d}
// (the value +- d, a number or [dx, dy, dz]; the value is the base scenario's after set:
// and grid:, so a key may be both set or gridded and jittered). Drawn numbers are rounded
// to 6 significant digits, and that value is the one used and recorded.
//
// Variants: the grid's combinations (one when there is no grid) times `draws`, grid-major;
// variant i's draws come from std::mt19937_64 seeded with splitmix64(splitmix64(seed) + i),
// the keys in the order written, through distributions written here from the raw 64-bit
// output (portable: not std::uniform_real_distribution), so the same file and seed give the
// same variants on every machine.
// Checks: the file's keys, types and ranges (file:line:col of the sweep file), then every
// variant is loaded as a scenario with its values as `--set` overrides and checked as
// `esim validate` checks it; an error names the sweep file's line, the key and the variant.
#pragma once

#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "sim/io/scenario.h"

namespace esim::app {

enum class KnobSource { Set, Grid, Random };
enum class DrawKind { None, Uniform, Integer, Choice, Jitter };

// one key of set:, grid: or random:
struct SweepKnob {
  std::string key;    // scenario key path, or path.offset_m / path.angle_deg / path.speed
  std::string where;  // "file:line:col" of the key in the sweep file
  KnobSource source = KnobSource::Set;
  // set: one value; grid: its values; choice: the choices (flow YAML text each)
  std::vector<std::string> values;
  std::vector<std::string> valueWhere;  // where each value is
  DrawKind draw = DrawKind::None;
  std::vector<double> lo, hi;  // uniform, integer: bounds; jitter: hi = half-widths
};

struct SweepSpec {
  std::string file;  // the sweep file as given
  std::string text;  // its text
  std::string name;
  std::string description;
  std::string base;       // the base scenario, resolved
  std::string baseWhere;  // where `base:` is
  std::uint64_t seed = 0;
  int draws = 1;
  std::vector<SweepKnob> knobs;  // set, grid, random; each in the order written
  std::vector<std::string> runOptions;
  std::string runOptionsWhere;
};

struct SweepVariant {
  int index = 0;
  std::string id;                      // "v0003"
  nlohmann::json values;               // the grid and random keys -> the values used
  std::vector<std::string> overrides;  // key=value on the base scenario, as --set
  Scenario scenario;                   // loaded and checked
};

// why an `esim run` option is the sweep's own to give (-o/--out, --overwrite, -q/--quiet:
// each run goes to DIR/runs/<id>/run, quiet; --set: a key under set:, checked and
// recorded), or "" when a sweep may pass it; run_options and --run-args both obey it
std::string sweepOwnedRunOption(const std::string& option);

// reads and checks a sweep file (not its variants); throws Error "file:line:col: ..."
SweepSpec loadSweepSpec(const std::string& path);
SweepSpec parseSweepSpec(const std::string& text, const std::string& sourceName);

// the number of variants (grid combinations x draws)
std::size_t sweepVariantCount(const SweepSpec& spec);

// "v0003": index zero-padded to at least 4 digits, and to the digits of count - 1
std::string variantId(std::size_t index, std::size_t count);

// every variant, loaded as a scenario and checked (withMesh: also the checks `esim
// validate` makes on a generated slab's mesh); throws Error naming the sweep file's line,
// the key and the variant
std::vector<SweepVariant> expandSweep(const SweepSpec& spec, bool withMesh = true);

// ---- portable draws (exposed for the tests) ----
std::uint64_t splitmix64(std::uint64_t x);
// the engine of variant i
std::mt19937_64 variantEngine(std::uint64_t seed, std::uint64_t index);
// [0, 1) from the top 53 bits of one output
double drawUnit(std::mt19937_64& engine);
// uniform in [0, n) by rejection (no modulo bias), n >= 1
std::uint64_t drawBelow(std::mt19937_64& engine, std::uint64_t n);
// v rounded to 6 significant digits (the value a draw uses and records)
double roundDrawn(double v);

}  // namespace esim::app
