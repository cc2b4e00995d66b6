#!/usr/bin/python3
"""Draws columns of a CSV the deep_ois tools write as a PNG line chart (matplotlib).

The tools (train_stabiliser, lens_log_fit, predict_lens, train, benchmark_online_learning) write
their data as CSV first and then run this script on it, so the data survives when matplotlib is
missing. It can also be run by hand on any of those CSVs:

  plot_csv.py lens_fold1.csv lens_fold1.png --x t_s --x-label "time [s]" \\
      --series logged_x_px "logged x" logged 1 --series predicted_x_px "predicted x" predicted 1 \\
      --series logged_y_px "logged y" logged 2 --series predicted_y_px "predicted y" predicted 2 \\
      --y-label "lens x [px]" --y-label "lens y [px]" --title "lens shift"

--series COLUMN LABEL [ROLE [PANEL]] adds one curve. ROLE:
  line       a plain curve (default; with markers where there are few points)
  logged     the measurement: thick and dark, drawn under the others
  predicted  a model's output: thin, coloured, drawn on top, so the logged curve stays visible
PANEL (1, 2, ...) stacks panels that share the x axis; --y-label is given once per panel.
Empty or non-numeric cells are gaps.

--bars LABEL_COLUMN VALUE_COLUMN draws one horizontal bar per row instead (evaluate's
bars_<category>.png from evaluation.csv), its value written beside it, "-" for an empty or
non-numeric value; --where COLUMN=VALUE keeps only the rows with that value (repeat), and
--x-label names the value's axis:

  plot_csv.py evaluation.csv bars_RE.png --bars method mean_px --where category=RE \\
      --x-label "geometry distance [px]" --title "Category RE"
 Exit status: 0 written, 1 bad input, 2 usage,
3 matplotlib missing (install Debian's python3-matplotlib).
"""

import argparse
import csv
import math
import sys

EXIT_BAD_INPUT = 1
EXIT_NO_MATPLOTLIB = 3
ROLES = ("line", "logged", "predicted")
DPI = 100


def parse_arguments(argv):
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog=__doc__.split("\n\n", 1)[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("csv", help="the CSV (header row, then numbers)")
    parser.add_argument("png", help="the PNG to write")
    parser.add_argument("--x", help="the x column (line charts)")
    parser.add_argument("--x-label", help="the x axis label (default: the column name)")
    parser.add_argument("--series", nargs="+", action="append", default=[],
                        metavar="COLUMN LABEL [ROLE [PANEL]]", help="one curve; repeat")
    parser.add_argument("--bars", nargs=2, metavar=("LABEL_COLUMN", "VALUE_COLUMN"),
                        help="a horizontal bar per row instead of curves")
    parser.add_argument("--where", action="append", default=[], metavar="COLUMN=VALUE",
                        help="keep only the rows where COLUMN is VALUE; repeat")
    parser.add_argument("--y-label", action="append", default=[], help="y axis label; once per panel")
    parser.add_argument("--title", default="", help="the figure title")
    parser.add_argument("--log-y", action="store_true", help="log scale on y (positive values)")
    parser.add_argument("--hline", type=float, action="append", default=[],
                        help="a grey reference line at this y; repeat")
    parser.add_argument("--size", default="1000x500", help="WIDTHxHEIGHT of the PNG in pixels")
    arguments = parser.parse_args(argv)
    if arguments.bars and (arguments.series or arguments.x):
        parser.error("--bars draws bars: it takes no --x or --series")
    if not arguments.bars and (not arguments.x or not arguments.series):
        parser.error("a line chart needs --x and at least one --series (or use --bars)")
    where = []
    for condition in arguments.where:
        if "=" not in condition:
            parser.error("--where '%s' is not COLUMN=VALUE" % condition)
        where.append(tuple(condition.split("=", 1)))
    arguments.where = where

    series = []
    for spec in arguments.series:
        if not 2 <= len(spec) <= 4:
            parser.error("--series takes COLUMN LABEL [ROLE [PANEL]], got %d words: %s"
                         % (len(spec), " ".join(spec)))
        role = spec[2] if len(spec) > 2 else "line"
        if role not in ROLES:
            parser.error("--series %s: role '%s' is not one of %s" % (spec[0], role, ", ".join(ROLES)))
        try:
            panel = int(spec[3]) if len(spec) > 3 else 1
        except ValueError:
            panel = 0
        if panel < 1:
            parser.error("--series %s: panel '%s' is not a number from 1" % (spec[0], spec[3]))
        series.append({"column": spec[0], "label": spec[1], "role": role, "panel": panel})
    arguments.series = series
    try:
        width, height = (int(v) for v in arguments.size.lower().split("x"))
        if width < 200 or height < 150:
            raise ValueError
    except ValueError:
        parser.error("--size '%s' is not WIDTHxHEIGHT pixels (at least 200x150)" % arguments.size)
    arguments.width_px, arguments.height_px = width, height
    return arguments


def number(text):
    try:
        value = float(text)
    except ValueError:
        return math.nan
    return value if math.isfinite(value) else math.nan


def read_table(path, wanted, where):
    """The wanted columns of the CSV's rows that pass `where` (COLUMN, VALUE pairs), as text."""
    with open(path, newline="") as stream:
        reader = csv.reader(stream)
        header = next(reader, None)
        if header is None:
            raise ValueError("%s: empty file (no header row)" % path)
        header = [name.strip() for name in header]
        needed = list(dict.fromkeys(list(wanted) + [column for column, _ in where]))
        missing = [name for name in needed if name not in header]
        if missing:
            raise ValueError("%s: no column %s (it has: %s)"
                             % (path, ", ".join(missing), ", ".join(header)))
        index = {name: header.index(name) for name in needed}
        columns = {name: [] for name in wanted}
        for row in reader:
            if not row:
                continue
            cell = lambda name: row[index[name]].strip() if index[name] < len(row) else ""
            if any(cell(column) != value for column, value in where):
                continue
            for name in wanted:
                columns[name].append(cell(name))
    return columns


def read_columns(path, wanted, where=()):
    """The wanted columns as lists of floats (NaN for empty or non-numeric cells)."""
    return {name: [number(cell) for cell in cells]
            for name, cells in read_table(path, wanted, where).items()}


def style(role, colour):
    if role == "logged":
        return {"color": "0.15", "linewidth": 2.4, "alpha": 0.55, "zorder": 2}
    if role == "predicted":
        return {"color": colour, "linewidth": 1.2, "zorder": 3}
    return {"color": colour, "linewidth": 1.6, "zorder": 3}


def label_log_axis(ax, values):
    """A log y axis with ticks written as plain numbers (0.05, not 5x10^-2), denser when the range
    is short; a range within a factor of 3 stays linear (a log axis would show no tick)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    positive = [v for v in values if math.isfinite(v) and v > 0]
    if not positive:
        return
    decades = math.log10(max(positive) / min(positive))
    if decades < math.log10(3.0):
        ax.ticklabel_format(axis="y", style="plain", useOffset=False)
        return
    ax.set_yscale("log")
    subs = (1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0) if decades < 1.5 else \
        (1.0, 2.0, 5.0) if decades < 3 else (1.0,)
    ax.yaxis.set_major_locator(LogLocator(base=10.0, subs=subs))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: "%g" % v))
    ax.yaxis.set_minor_formatter(NullFormatter())


def draw(arguments, columns, plt):
    panels = max(s["panel"] for s in arguments.series)
    figure, axes = plt.subplots(panels, 1, sharex=True, squeeze=False, constrained_layout=True,
                                figsize=(arguments.width_px / DPI, arguments.height_px / DPI), dpi=DPI)
    axes = axes[:, 0]
    x = columns[arguments.x]
    palette = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for panel, ax in enumerate(axes, start=1):
        drawn = [s for s in arguments.series if s["panel"] == panel]
        # Logged curves first: the predicted ones are drawn over them, thinner.
        drawn.sort(key=lambda s: 0 if s["role"] == "logged" else 1)
        # A model's output in red over the grey measurement (the strongest contrast), other
        # curves in the default cycle.
        colour_index = 0
        for s in drawn:
            colour = "tab:red" if s["role"] == "predicted" else palette[colour_index % len(palette)]
            if s["role"] != "logged":
                colour_index += 1
            y = columns[s["column"]]
            points = [(a, b) for a, b in zip(x, y) if math.isfinite(a) and math.isfinite(b)]
            if arguments.log_y:
                points = [(a, b) if b > 0 else (a, math.nan) for a, b in points]
            kwargs = style(s["role"], colour)
            if s["role"] == "line" and len(points) <= 40:
                kwargs["marker"] = "o"
                kwargs["markersize"] = 4
            ax.plot([p[0] for p in points], [p[1] for p in points], label=s["label"], **kwargs)
        for value in arguments.hline:
            ax.axhline(value, color="0.4", linewidth=1.0, linestyle="--", zorder=1)
        if arguments.log_y:
            label_log_axis(ax, [p for s in drawn for p in columns[s["column"]]])
        ax.grid(True, which="major", color="0.88", linewidth=0.8)
        ax.minorticks_on()
        ax.tick_params(which="minor", length=2)
        if panel - 1 < len(arguments.y_label):
            ax.set_ylabel(arguments.y_label[panel - 1])
        if drawn:
            # Outside the axes, on the right: a legend never hides a curve.
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, frameon=False)
    axes[-1].set_xlabel(arguments.x_label or arguments.x)
    if arguments.title:
        figure.suptitle(arguments.title)
    figure.savefig(arguments.png, dpi=DPI)
    plt.close(figure)


def draw_bars(arguments, labels, values, plt):
    figure, ax = plt.subplots(constrained_layout=True, dpi=DPI,
                              figsize=(arguments.width_px / DPI, arguments.height_px / DPI))
    palette = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    rows = list(range(len(labels)))
    finite = [v for v in values if math.isfinite(v)]
    largest = max(finite) if finite else 1.0
    ax.barh(rows, [v if math.isfinite(v) else 0.0 for v in values], height=0.7,
            color=palette[0], zorder=2)
    for row, value in zip(rows, values):
        text = "%.3f" % value if math.isfinite(value) else "-"
        ax.text((value if math.isfinite(value) else 0.0) + 0.01 * largest, row, text,
                va="center", ha="left", fontsize=9, zorder=3)
    ax.set_yticks(rows)
    ax.set_yticklabels(labels)
    ax.invert_yaxis()  # the first row on top, as in the table
    ax.set_xlim(0.0, largest * 1.15 if largest > 0 else 1.0)
    ax.grid(True, axis="x", color="0.88", linewidth=0.8, zorder=0)
    ax.minorticks_on()
    ax.tick_params(axis="y", which="minor", left=False)
    ax.set_xlabel(arguments.x_label or arguments.bars[1])
    if arguments.title:
        ax.set_title(arguments.title)
    figure.savefig(arguments.png, dpi=DPI)
    plt.close(figure)


def main(argv):
    arguments = parse_arguments(argv)
    try:
        import matplotlib
        matplotlib.use("Agg")  # no display needed
        import matplotlib.pyplot as plt
    except ImportError as error:
        sys.stderr.write("plot_csv: matplotlib is missing (%s); install Debian's python3-matplotlib "
                         "(scripts/install_deps.sh). The data is in %s.\n" % (error, arguments.csv))
        return EXIT_NO_MATPLOTLIB
    try:
        if arguments.bars:
            label_column, value_column = arguments.bars
            table = read_table(arguments.csv, [label_column, value_column], arguments.where)
            if not table[label_column]:
                raise ValueError("%s: no row where %s" % (arguments.csv, ", ".join(
                    "%s is %s" % condition for condition in arguments.where)))
        else:
            wanted = [arguments.x] + [s["column"] for s in arguments.series]
            columns = read_columns(arguments.csv, list(dict.fromkeys(wanted)), arguments.where)
    except (OSError, ValueError) as error:
        sys.stderr.write("plot_csv: %s\n" % error)
        return EXIT_BAD_INPUT
    try:
        if arguments.bars:
            draw_bars(arguments, table[label_column], [number(v) for v in table[value_column]], plt)
        else:
            draw(arguments, columns, plt)
    except (OSError, ValueError) as error:
        sys.stderr.write("plot_csv: %s: %s\n" % (arguments.png, error))
        return EXIT_BAD_INPUT
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
