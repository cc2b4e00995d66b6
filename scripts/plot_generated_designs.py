#!/usr/bin/python3
"""Draws the contact sheet of the generated stabiliser designs (docs/simulator.md): one row per
design class, a few designs per row, each the lens shift against what the camera's gyro says a
lens would have to do to cancel all of the rotation (f times the integrated rate, no centring).

Input: the CSV pair written by `sim_contact_sheet --designs-csv FILE.csv` (FILE.csv with the
traces, FILE_designs.csv with the designs). Needs python3-matplotlib (scripts/install_deps.sh).

    rosrun deep_ois sim_contact_sheet --designs-csv /tmp/designs.csv
    /usr/bin/python3 scripts/plot_generated_designs.py /tmp/designs.csv \
        --out docs/generated_designs_contact_sheet.png
"""
import argparse
import csv
import sys
import textwrap
from collections import OrderedDict, defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_designs(path):
    designs = OrderedDict()
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            designs[int(row["design_seed"])] = row
    return designs


def read_traces(path):
    traces = defaultdict(lambda: defaultdict(list))
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            trace = traces[int(row["design_seed"])]
            for key in ("t_s", "gyro_x_rad_s", "gyro_y_rad_s", "lens_x_px", "lens_y_px"):
                trace[key].append(float(row[key]))
    return traces


def integrate(t, rate):
    """Trapezoidal integral of rate over t, starting at 0."""
    angle = [0.0]
    for i in range(1, len(t)):
        angle.append(angle[-1] + 0.5 * (rate[i] + rate[i - 1]) * (t[i] - t[i - 1]))
    return angle


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("traces", help="FILE.csv from sim_contact_sheet --designs-csv")
    parser.add_argument("--designs", help="the designs' list (default: FILE_designs.csv)")
    parser.add_argument("--out", required=True, help="the PNG to write")
    args = parser.parse_args()
    designs_path = args.designs or args.traces[: -len(".csv")] + "_designs.csv"
    designs = read_designs(designs_path)
    traces = read_traces(args.traces)
    if not designs or not traces:
        sys.exit("plot_generated_designs: no designs in %s or no traces in %s" % (designs_path, args.traces))

    by_class = OrderedDict()
    for seed, design in designs.items():
        by_class.setdefault(design["class"], []).append(seed)
    columns = max(len(seeds) for seeds in by_class.values())
    fig, axes = plt.subplots(len(by_class), columns, figsize=(5.2 * columns, 3.3 * len(by_class)),
                             sharex=True, squeeze=False)
    for r, (name, seeds) in enumerate(by_class.items()):
        for c in range(columns):
            ax = axes[r][c]
            if c >= len(seeds):
                ax.axis("off")
                continue
            seed = seeds[c]
            design, trace = designs[seed], traces[seed]
            f = float(design["focal_px"])
            t = trace["t_s"]
            # The shift that cancels all of the rotation: f (angle_y, -angle_x) (docs/simulator.md).
            full_x = [f * a for a in integrate(t, trace["gyro_y_rad_s"])]
            full_y = [-f * a for a in integrate(t, trace["gyro_x_rad_s"])]
            ax.plot(t, full_x, color="0.6", lw=0.8, label="x: f x gyro angle (no centring)")
            ax.plot(t, trace["lens_x_px"], color="tab:blue", lw=1.1, label="x: lens")
            ax.plot(t, full_y, color="0.6", lw=0.8, ls="--", label="y: -f x gyro angle")
            ax.plot(t, trace["lens_y_px"], color="tab:orange", lw=1.1, label="y: lens")
            ax.set_ylim(-9, 9)
            ax.grid(True, lw=0.3)
            features = [tag for tag in design["features"].split() if tag != name]
            title = "design %d (%s)\n%s" % (seed, design["split"].replace("_", " "),
                                            textwrap.fill(", ".join(features), 62))
            ax.set_title(title, fontsize=7.5, loc="left")
            if c == 0:
                ax.set_ylabel("%s\nshift (px)" % name.replace("_", " "), fontsize=10)
            if r == len(by_class) - 1:
                ax.set_xlabel("time (s)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=4, fontsize=9, frameon=False)
    fig.suptitle("Generated stabiliser designs: the lens against the camera gyro's full-cancellation "
                 "shift (same hand-held motion for all, f = %g px)" % float(next(iter(designs.values()))["focal_px"]),
                 fontsize=11, y=0.995)
    fig.tight_layout(rect=(0, 0, 1, 0.965))
    fig.savefig(args.out, dpi=80)
    print("plot_generated_designs: wrote %s (%d designs)" % (args.out, len(designs)))


if __name__ == "__main__":
    main()
