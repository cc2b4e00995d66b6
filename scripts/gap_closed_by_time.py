#!/usr/bin/env python3
"""Gap closed per compensation row of an `evaluate --out` run, split by time in the sequence.

    python3 scripts/gap_closed_by_time.py DIR/evaluation_pairs.csv [--split 1.0]

For pairs whose frame a is less than --split seconds after its recording's first pair, and for the
rest: each row's mean capped distance (the paper's metric, over all categories' pairs at once)
and the share of the gap between the uncompensated OIS gyro and the non-OIS twin's gyro it closed.
A start-up transient (a stabiliser starting centred and at rest) shows as a lower figure early.
"""
import argparse
import collections
import csv
import sys

OIS_GYRO = "gyro, OIS camera (uncompensated)"
TWIN_GYRO = "gyro, non-OIS camera"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pairs_csv", help="evaluation_pairs.csv written by evaluate --out")
    parser.add_argument("--split", type=float, default=1.0, help="seconds after the first pair")
    args = parser.parse_args()
    try:
        with open(args.pairs_csv, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"gap_closed_by_time: {e}")
    needed = {"recording", "stamp_a", "method", "scored_px"}
    if not rows or not needed <= set(rows[0]):
        sys.exit(f"gap_closed_by_time: {args.pairs_csv}: expected the columns {sorted(needed)}")
    first = {}
    for r in rows:
        first[r["recording"]] = min(first.get(r["recording"], float("inf")), float(r["stamp_a"]))
    sums = collections.defaultdict(lambda: [0.0, 0])
    for r in rows:
        early = float(r["stamp_a"]) - first[r["recording"]] < args.split
        entry = sums[(r["method"], early)]
        entry[0] += float(r["scored_px"])
        entry[1] += 1
    methods = sorted({method for method, _ in sums})
    for early in (True, False):
        label = f"first {args.split:g} s" if early else f"after {args.split:g} s"
        mean = {m: sums[(m, early)][0] / sums[(m, early)][1] for m in methods if sums[(m, early)][1]}
        if OIS_GYRO not in mean or TWIN_GYRO not in mean:
            print(f"{label}: no pairs of both gyro rows (a recording and its non-OIS twin needed)")
            continue
        gap = mean[OIS_GYRO] - mean[TWIN_GYRO]
        print(f"{label}: {sums[(OIS_GYRO, early)][1]} OIS pairs")
        for m in methods:
            if m in (OIS_GYRO, TWIN_GYRO, "identity") or m not in mean:
                continue
            print(f"  {m}: {mean[m]:.3f} px capped, {100.0 * (mean[OIS_GYRO] - mean[m]) / gap:.1f} % of the gap")


if __name__ == "__main__":
    main()
