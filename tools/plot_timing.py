#!/usr/bin/env python3
"""plot_timing.py - timing.png of an ESim run folder (called by `esim plot` and `esim run --plots`).

Usage: plot_timing.py RUN_DIR [-o PNG]

1. Read RUN_DIR/timing.csv (a row per frame, a column per stage) and RUN_DIR/timing.json
   (budget, scenario, the phases the scene has).
2. Top panel: per frame, the interactive stages stacked (physics stages, snapshot, render),
   the 33.3 ms budget line, frames that waited for a background rebuild marked; frames
   taller than the axis (rebuilds) are clipped and drawn as triangles with their total. The
   frame period (period_ms: between frames done, what a viewer sees; with the drawing on
   its own thread it is shorter than the stacked sum) as a line, clipped to the axis.
3. Lower panels, where the scene has them: Joule power and maximum temperature, and the
   tets removed so far.
4. Write RUN_DIR/timing.png (or -o).

Exit status: 0 written; 2 bad input (no such run folder, unreadable CSV); 3 matplotlib is
missing (install python3-matplotlib: tools/install-deps).
"""
import argparse
import csv
import json
import os
import sys

EXIT_BAD_INPUT = 2
EXIT_NO_MATPLOTLIB = 3

# the stages of the interactive time, in frame order (sim/simulation.h); encode is the
# frame loop's wait on the encoder queue, outside the 30 Hz budget
INTERACTIVE_STAGES = [
    "move_tool", "find_contacts", "solve_potential", "heat", "solve_stress", "rupture",
    "rebuild", "snapshot", "render",
]


def fail(code, message):
    print("plot_timing: " + message, file=sys.stderr)
    sys.exit(code)


def read_run(run_dir):
    csv_path = os.path.join(run_dir, "timing.csv")
    if not os.path.isfile(csv_path):
        fail(EXIT_BAD_INPUT, "%s: no timing.csv (expected an ESim run folder)" % run_dir)
    try:
        with open(csv_path, newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            lines = list(reader)
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        fail(EXIT_BAD_INPUT, "%s: cannot be read: %s" % (csv_path, e))
    if not header or "interactive_ms" not in header:
        fail(EXIT_BAD_INPUT, "%s: no interactive_ms column (not an ESim timing.csv)" % csv_path)
    if not lines:
        fail(EXIT_BAD_INPUT, "%s: no frames (a header and no rows)" % csv_path)
    # every cell a number, "skipped" (a stage with nothing to do) or empty (absent): a cut or
    # edited file was drawn with its bad cells as 0
    for i, cells in enumerate(lines):
        where = "%s:%d" % (csv_path, i + 2)
        if len(cells) != len(header):
            fail(EXIT_BAD_INPUT, "%s: %d fields where the header has %d (a cut or edited file?)"
                 % (where, len(cells), len(header)))
        for name, cell in zip(header, cells):
            if cell in ("", "skipped"):
                continue
            try:
                float(cell)
            except ValueError:
                fail(EXIT_BAD_INPUT, "%s: %s = '%s' is not a number" % (where, name, cell[:40]))
    rows = [dict(zip(header, cells)) for cells in lines]
    info = {}
    json_path = os.path.join(run_dir, "timing.json")
    if os.path.isfile(json_path):
        try:
            with open(json_path, encoding="utf-8") as f:
                info = json.load(f)
        except (OSError, UnicodeDecodeError, ValueError) as e:
            fail(EXIT_BAD_INPUT, "%s: not readable JSON: %s" % (json_path, e))
        if not isinstance(info, dict):
            fail(EXIT_BAD_INPUT, "%s: expected a JSON object" % json_path)
        budget = info.get("budget_ms", 1000.0 / 30.0)
        if isinstance(budget, bool) or not isinstance(budget, (int, float)) or not budget > 0:
            fail(EXIT_BAD_INPUT, "%s: budget_ms = %r; expected a number > 0" % (json_path, budget))
        if not isinstance(info.get("mesh", {}), dict):
            fail(EXIT_BAD_INPUT, "%s: mesh: expected an object" % json_path)
        if not isinstance(info.get("physics", []), list):
            fail(EXIT_BAD_INPUT, "%s: physics: expected a list" % json_path)
    return rows, info


def number(text):
    # "skipped" (the stage had nothing to do: microseconds) and "" (absent) count as 0
    try:
        return float(text)
    except (TypeError, ValueError):
        return 0.0


def main():
    parser = argparse.ArgumentParser(description="timing.png of an ESim run folder")
    parser.add_argument("run_dir")
    parser.add_argument("-o", "--out", help="PNG to write (default RUN_DIR/timing.png)")
    args = parser.parse_args()
    rows, info = read_run(args.run_dir)
    out = args.out or os.path.join(args.run_dir, "timing.png")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        fail(EXIT_NO_MATPLOTLIB,
             "matplotlib is missing for %s (Debian: apt-get install python3-matplotlib, or "
             "tools/install-deps); no timing.png written" % sys.executable)

    # ---- 1. the series ----
    budget = float(info.get("budget_ms", 1000.0 / 30.0))
    time_s = [number(r["time_s"]) for r in rows]
    header = rows[0].keys() if rows else []
    stages = [s for s in INTERACTIVE_STAGES if s + "_ms" in header]
    stage_ms = {s: [number(r[s + "_ms"]) for r in rows] for s in stages}
    total = [number(r["interactive_ms"]) for r in rows]
    waits = [number(r.get("rebuild_wait_ms")) for r in rows]
    physics = info.get("physics", [])
    has_power = "electric" in physics if physics else "power_w" in header
    has_temp = "thermal" in physics if physics else False
    has_removed = "removed_tets" in header
    dt = (time_s[1] - time_s[0]) if len(time_s) > 1 else 1.0 / 30.0

    # ---- 2. stacked stage times ----
    lower = int(has_power or has_temp) + int(has_removed)
    heights = [3] + [1.4] * lower
    fig, axes = plt.subplots(1 + lower, 1, sharex=True, figsize=(11, 4 + 1.8 * lower),
                             gridspec_kw={"height_ratios": heights}, squeeze=False)
    axes = axes[:, 0]
    ax = axes[0]
    ordered = sorted(total)
    p95 = ordered[int(0.95 * (len(ordered) - 1))] if ordered else budget
    top = max(1.6 * budget, 1.3 * p95)
    clip = bool(total) and max(total) > 1.5 * top
    if not clip and total:
        top = max(top, 1.05 * max(total))
    colors = plt.get_cmap("tab10")
    base = [0.0] * len(rows)
    for i, s in enumerate(stages):
        upper = [b + v for b, v in zip(base, stage_ms[s])]
        if max(stage_ms[s], default=0) > 0:
            ax.fill_between(time_s, base, upper, step="mid", color=colors(i % 10), linewidth=0,
                            label=s)
        base = upper
    ax.axhline(budget, color="crimson", linestyle="--", linewidth=1.2,
               label="%.1f ms (30 Hz)" % budget)
    if "period_ms" in header:
        periods = [number(r["period_ms"]) for r in rows]
        over_period = sum(1 for p in periods if p > budget)
        ax.step(time_s, [min(p, top) for p in periods], where="mid", color="black",
                linewidth=0.9, label="frame period (%d over)" % over_period)
    over = sum(1 for t in total if t > budget)
    if clip:
        xs = [t for t, v in zip(time_s, total) if v > top]
        ax.plot(xs, [top] * len(xs), "v", color="black", markersize=5, clip_on=False,
                label="beyond the axis (total ms)")
        for t, v in zip(time_s, total):
            if v > top:
                ax.annotate("%.0f" % v, (t, top), textcoords="offset points", xytext=(0, 4),
                            ha="center", fontsize=6, annotation_clip=False)
    wait_x = [t for t, w in zip(time_s, waits) if w > 0]
    if wait_x:
        wait_y = [min(v, top) for v, w in zip(total, waits) if w > 0]
        ax.plot(wait_x, wait_y, "o", markerfacecolor="none", markeredgecolor="black",
                markersize=7, label="waited for the rebuild (%d frames)" % len(wait_x))
    ax.set_ylim(0, top * (1.08 if clip else 1.0))
    ax.set_ylabel("ms per frame")
    name = info.get("scenario", os.path.basename(os.path.normpath(args.run_dir)))
    mesh = info.get("mesh", {})
    title = "%s: %d frames, %d over %.1f ms" % (name, len(rows), over, budget)
    if mesh:
        title += "  (%s nodes, %s tets)" % (mesh.get("nodes", "?"), mesh.get("tets", "?"))
    if info.get("complete") is False:
        title += "  PARTIAL"
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=7, ncol=4, framealpha=0.85)
    ax.grid(axis="y", alpha=0.3)

    # ---- 3. power, temperature, removed tets ----
    k = 1
    if has_power or has_temp:
        axp = axes[k]
        k += 1
        handles = []
        if has_power:
            handles += axp.plot(time_s, [number(r["power_w"]) for r in rows], color="tab:blue",
                                label="Joule power [W]")
            axp.set_ylabel("power [W]")
        if has_temp:
            axt = axp.twinx() if has_power else axp
            handles += axt.plot(time_s, [number(r["max_temperature_c"]) for r in rows],
                                color="tab:red", label="max temperature [C]")
            axt.set_ylabel("max temperature [C]")
        axp.legend(handles=handles, loc="upper left", fontsize=7)
        axp.grid(alpha=0.3)
    if has_removed:
        axr = axes[k]
        removed, so_far = [], 0
        for r in rows:
            so_far += int(number(r["removed_tets"]))
            removed.append(so_far)
        axr.step(time_s, removed, where="post", color="tab:brown", label="tets removed so far")
        axr.set_ylabel("removed tets")
        axr.legend(loc="upper left", fontsize=7)
        axr.grid(alpha=0.3)
    axes[-1].set_xlabel("simulated time [s] (frame every %.1f ms)" % (dt * 1000))
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
