#!/usr/bin/python3
"""Reads the curves back out of a learning-curve PNG that benchmark_online_learning drew with its
old OpenCV chart (src/tools/support/line_plot.cpp, removed in 94da1fe), whose data was never
written: 800x500 canvas, plot area x 80..780, y 40..440, window k (1..n) at x = 80 + (k-1)/(n-1)*700,
y = 440 - (v - lo)/(hi - lo)*400 rounded to a pixel, hi and lo printed at the axis (%.4g).

Each segment between two windows is fitted as a straight line through the centre of its
anti-aliased curve pixels column by column (its ends excluded), and extended to the windows; a
window's value is the mean of its two segments' ends. Writes window_end_s, learning_pct, fixed_pct.
usage: recover.py CHART.png HI LO WINDOWS OUT.csv
"""
import sys
import numpy as np
from PIL import Image

LEFT, TOP, WIDTH, HEIGHT = 80, 40, 700, 400
LEGEND = (555, 48, 600, 84)  # x0, y0, x1, y1 of the legend's colour swatches


def weights(image, colour):
    """How much of the curve colour each pixel holds (anti-aliased over white), 0 elsewhere."""
    rgb = image.astype(float)
    colour = np.array(colour, float)
    # alpha from the channel where the colour is darkest against white
    channel = int(np.argmin(colour))
    alpha = (255.0 - rgb[..., channel]) / (255.0 - colour[channel])
    predicted = 255.0 * (1 - alpha[..., None]) + colour * alpha[..., None]
    good = (np.abs(rgb - predicted).max(axis=2) < 14) & (alpha > 0.25)
    w = np.where(good, np.clip(alpha, 0, 1), 0.0)
    x0, y0, x1, y1 = LEGEND
    w[y0:y1, x0:x1] = 0.0
    return w


def series(image, colour, n):
    w = weights(image, colour)
    xs = [LEFT + round((k / (n - 1)) * WIDTH) for k in range(n)]
    ends = [[] for _ in range(n)]
    for k in range(n - 1):
        cols, ys, ws = [], [], []
        for c in range(xs[k] + 3, xs[k + 1] - 2):
            column = w[TOP - 3:TOP + HEIGHT + 4, c]
            if column.sum() < 0.5:
                continue
            rows = np.arange(TOP - 3, TOP + HEIGHT + 4)
            cols.append(c)
            ys.append((column * rows).sum() / column.sum())
            ws.append(column.sum())
        if len(cols) < 4:
            continue
        b, a = np.polyfit(cols, ys, 1, w=np.sqrt(ws))
        ends[k].append(a + b * xs[k])
        ends[k + 1].append(a + b * xs[k + 1])
    return [float(np.mean(e)) if e else float('nan') for e in ends]


def main():
    chart, hi, lo, n, out = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
    image = np.array(Image.open(chart).convert('RGB'))
    to_value = lambda y: lo + (TOP + HEIGHT - y) / HEIGHT * (hi - lo)
    learning = [to_value(y) for y in series(image, (0, 80, 200), n)]
    fixed = [to_value(y) for y in series(image, (200, 0, 0), n)]
    with open(out, 'w') as f:
        f.write('window_end_s,learning_pct,fixed_pct\n')
        for k in range(n):
            f.write('%g,%.2f,%.2f\n' % (10 * (k + 1), learning[k], fixed[k]))


main()
