#!/usr/bin/python3
"""Draws the contact sheet of the generated stabiliser designs (docs/simulator.md): one row per
design class, a few designs per row, all on the same hand-held motion: each design's lens shift
(x and y) against one reference computed from the camera's gyro, f times the gyro angle about the
camera's y axis high-passed at 0.3 Hz (the x shift a plain first-order stabiliser would command,
stroke ignored). Centring, strokes, pan handling, gain and delay show as departures from it.

Input: the CSV pair written by `sim_contact_sheet --designs-csv FILE.csv` (FILE.csv with the
traces, FILE_designs.csv with the designs). Needs python3-matplotlib (scripts/install_deps.sh).

    rosrun deep_ois sim_contact_sheet --designs-csv /tmp/designs.csv
    /usr/bin/python3 scripts/plot_generated_designs.py /tmp/designs.csv \
        --out docs/generated_designs_contact_sheet.png
"""
import argparse
import csv
import math
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


def highpass(t, rate, corner_hz):
    """The leaky integral y' = rate - 2 pi corner y (a first-order high-passed angle), from 0."""
    w = 2.0 * math.pi * corner_hz
    angle = [0.0]
    for i in range(1, len(t)):
        dt = t[i] - t[i - 1]
        decay = math.exp(-w * dt)
        angle.append(decay * angle[-1] + (1.0 - decay) / w * 0.5 * (rate[i] + rate[i - 1]))
    return angle


REFERENCE_CORNER_HZ = 0.3


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
            # s = f (angle_y, -angle_x) cancels the rotation (docs/simulator.md); x only, as reference.
            reference_x = [f * a for a in highpass(t, trace["gyro_y_rad_s"], REFERENCE_CORNER_HZ)]
            ax.plot(t, reference_x, color="black", lw=0.7,
                    label="reference: f x gyro angle (y), high-passed at %g Hz" % REFERENCE_CORNER_HZ)
            ax.plot(t, trace["lens_x_px"], color="tab:blue", lw=1.2, label="lens x")
            ax.plot(t, trace["lens_y_px"], color="tab:orange", lw=0.9, alpha=0.75, label="lens y")
            ax.set_ylim(-8, 8)
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
    fig.suptitle("Generated stabiliser designs: the lens shift of a few designs per class, all on the same "
                 "hand-held motion (f = %g px, 8 s)" % float(next(iter(designs.values()))["focal_px"]),
                 fontsize=12, y=0.995)
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.978), ncol=3, fontsize=10,
               frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.955))
    fig.savefig(args.out, dpi=80)
    # A palette image is a third of the size of matplotlib's RGBA for the same look (Pillow comes
    # with python3-matplotlib).
    from PIL import Image
    Image.open(args.out).convert("RGB").quantize(colors=64).save(args.out, optimize=True)
    print("plot_generated_designs: wrote %s (%d designs)" % (args.out, len(designs)))


if __name__ == "__main__":
    main()
