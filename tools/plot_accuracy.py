#!/usr/bin/env python3
"""plot_accuracy.py - accuracy_vs_time.png of `esim bench accuracy` (called by the bench).

Usage: plot_accuracy.py accuracy.csv [-o PNG]

Panels, each error against the time per frame (physics + render medians, ms), log axes,
one series per knob (the points of a knob joined in the order of the sweep): groove depth,
1 - IoU of the removed region, delivered energy, probe temperatures (RMS, K), and the
render-only PSNR of the last frame against per-pixel shading + 4x MSAA (dB, linear axis:
higher is better) against the render time per frame. The paper's set-up (uniform 1013
nodes) and the shipped slab_cut set-up are marked; the Pareto front of each error is
circled.

Exit status: 0 written; 2 bad input; 3 matplotlib is missing (python3-matplotlib).
"""
import argparse
import csv
import os
import sys

EXIT_BAD_INPUT = 2
EXIT_NO_MATPLOTLIB = 3
FLOOR = 1e-3  # errors below (exactly 0: the same discrete answer) are drawn here (log axes)


def fail(code, message):
    print("plot_accuracy: " + message, file=sys.stderr)
    sys.exit(code)


def value(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def main():
    parser = argparse.ArgumentParser(description="accuracy_vs_time.png of esim bench accuracy")
    parser.add_argument("csv")
    parser.add_argument("-o", "--out", help="PNG (default: accuracy_vs_time.png next to the CSV)")
    args = parser.parse_args()
    if not os.path.isfile(args.csv):
        fail(EXIT_BAD_INPUT, "%s: no such file" % args.csv)
    with open(args.csv, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r.get("knob") != "reference" and not r.get("error")]
    if not rows or "frame_ms" not in rows[0]:
        fail(EXIT_BAD_INPUT, "%s: no points (expected esim bench accuracy's CSV)" % args.csv)
    out = args.out or os.path.join(os.path.dirname(args.csv) or ".", "accuracy_vs_time.png")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        fail(EXIT_NO_MATPLOTLIB,
             "matplotlib is missing for %s (Debian: apt-get install python3-matplotlib, or "
             "tools/install-deps); no accuracy_vs_time.png written" % sys.executable)

    panels = [("depth_err", "groove depth error (relative)", "pareto_depth", True),
              ("iou", "1 - IoU of the removed region", "pareto_iou", True),
              ("energy_err", "delivered energy error (relative)", "pareto_energy", True),
              ("probe_rms_k", "probe temperature error, RMS [K]", None, True),
              ("psnr_render_db", "render only: last frame PSNR against per-pixel\nshading + 4x MSAA [dB]", None, False)]
    knobs = []
    for r in rows:
        if r["knob"] not in knobs:
            knobs.append(r["knob"])
    # the baseline point belongs to every knob's series (each knob is swept from it)
    baseline = [r for r in rows if r.get("baseline") == "1"]
    colors = plt.get_cmap("tab10")
    fig, axes = plt.subplots(2, 3, figsize=(16, 9.5))
    axes = axes.ravel()
    for ax, (column, label, front, log_y) in zip(axes, panels):
        for k, knob in enumerate(knobs):
            pts = []
            for r in rows:
                if r["knob"] != knob and not (r in baseline):
                    continue
                x = value(r["render_median_ms" if column == "psnr_render_db" else "frame_ms"])
                y = value(r[column])
                if x is None or y is None:
                    continue
                if column == "iou":
                    y = 1 - y
                if log_y:
                    y = max(y, FLOOR)
                pts.append((x, y, r))
            if not pts:
                continue
            pts.sort(key=lambda p: p[0])
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", color=colors(k % 10),
                    markersize=4, linewidth=1, label=knob)
            for x, y, r in pts:
                if front and r.get(front) == "1":
                    ax.plot(x, y, "o", markersize=11, markerfacecolor="none",
                            markeredgecolor="black", linewidth=0.8)
                if r.get("mark") and r["knob"] == knob:
                    ax.plot(x, y, "*" if r["mark"] == "paper" else "s", markersize=13,
                            color="gold", markeredgecolor="black", zorder=5)
                    ax.annotate(r["mark"], (x, y), textcoords="offset points", xytext=(6, 6),
                                fontsize=8, fontweight="bold")
                if knob in ("mesh_graded", "mesh_uniform") and r["knob"] == knob:
                    ax.annotate(r["value"], (x, y), textcoords="offset points", xytext=(4, -10),
                                fontsize=6, color=colors(k % 10))
        ax.set_xscale("log")
        if log_y:
            ax.set_yscale("log")
        ax.set_xlabel("render ms per frame (snapshot + draw, median)" if column == "psnr_render_db"
                      else "ms per frame (physics + render, median)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.25)
    axes[0].legend(fontsize=8, loc="best")
    axes[-1].axis("off")
    axes[-1].text(0.0, 0.9,
                  "One series per knob, each swept alone from the baseline.\n"
                  "Circles: Pareto front of that error (time against error).\n"
                  "Gold star: the paper's set-up (uniform 1013 nodes).\n"
                  "Gold square: the shipped slab_cut set-up, the baseline\n"
                  "(graded 8000 nodes, updated in place, explicit heat, 30 fps).\n"
                  "Every series passes through the baseline.\n"
                  "Errors below %g (0: the same discrete cut) are drawn at %g." % (FLOOR, FLOOR),
                  fontsize=10, va="top", transform=axes[-1].transAxes)
    fig.suptitle("esim bench accuracy: what accuracy costs in time (%s)" %
                 os.path.basename(args.csv))
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    return 0


if __name__ == "__main__":
    sys.exit(main())
