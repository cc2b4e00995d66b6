#!/usr/bin/env python3
"""Coverage of a calibration 1-sigma rule on calibration_benchmark CSV files.

The benchmark's CSV (--csv) holds, per bag, the error of every quantity and its statistical 1-sigma
(CalibrationResult::statistical). This script evaluates the rule the calibration reports,
    reported = sqrt((factor * statistical)^2 + systematic^2),
for the given factor and systematic terms, or for a grid of them (--grid), without re-running the
calibration: how many errors the reported 1-sigma covers, and the median reported 1-sigma, per
quantity and lens kind (docs/calibration_uncertainty.md).

  python3 scripts/calibration_coverage.py hh7.csv pr7.csv
  python3 scripts/calibration_coverage.py --factor 2 --offset-ms 0.1 hh7.csv pr7.csv
  python3 scripts/calibration_coverage.py --grid hh7.csv pr7.csv
"""
import argparse
import csv
import math

QUANTITIES = {
    # name: (error column(s), statistical column(s), unit)
    "offset": (["offset_error_ms"], ["offset_statistical_ms"], "ms"),
    "readout": (["readout_error_ms"], ["readout_statistical_ms"], "ms"),
    "rotation": ([f"rotation_error_deg_{a}" for a in "xyz"], [f"rotation_statistical_deg_{a}" for a in "xyz"], "deg"),
    "bias": ([f"bias_error_mrad_s_{a}" for a in "xyz"], [f"bias_statistical_mrad_s_{a}" for a in "xyz"], "mrad/s"),
}
GRID = {"offset": [0.0, 0.05, 0.08, 0.1, 0.15], "readout": [0.0, 0.1, 0.12, 0.15, 0.2, 0.25],
        "rotation": [0.0, 0.1, 0.15, 0.2, 0.3], "bias": [0.0, 0.5, 0.8, 1.0, 1.5]}


def upper_median(values):
    """The benchmark's median: for an even count the upper of the two middle values."""
    ordered = sorted(values)
    return ordered[len(ordered) // 2] if ordered else float("nan")


def pairs(rows, quantity):
    """(error, statistical sigma) of every estimated axis; held quantities (sigma 0) are skipped."""
    errors, sigmas, _ = QUANTITIES[quantity]
    out = []
    for row in rows:
        for e, s in zip(errors, sigmas):
            sigma = float(row[s])
            if sigma > 0.0:
                out.append((float(row[e]), sigma))
    return out


def coverage(items, factor, systematic):
    reported = [math.hypot(factor * sigma, systematic) for _, sigma in items]
    covered = sum(abs(error) <= r for (error, _), r in zip(items, reported))
    return covered, len(items), upper_median(reported)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("csv", nargs="+", help="calibration_benchmark --csv output(s)")
    parser.add_argument("--factor", type=float, default=2.5, help="statistical_sigma_factor (2.5)")
    parser.add_argument("--offset-ms", type=float, default=0.08, help="systematic time offset (0.08 ms)")
    parser.add_argument("--readout-ms", type=float, default=0.12, help="systematic readout (0.12 ms)")
    parser.add_argument("--rotation-deg", type=float, default=0.2, help="systematic rotation per axis (0.2 deg)")
    parser.add_argument("--bias-mrad-s", type=float, default=0.8, help="systematic bias per axis (0.8 mrad/s)")
    parser.add_argument("--grid", action="store_true", help="a grid of factors and systematic terms instead")
    args = parser.parse_args()

    rows = []
    for path in args.csv:
        with open(path, newline="") as f:
            rows += [r for r in csv.DictReader(f) if r.get("offset_statistical_ms", "") != ""]
    kinds = [("non-OIS", [r for r in rows if r["ois"] == "0"]), ("OIS", [r for r in rows if r["ois"] == "1"]),
             ("all", rows)]
    systematic = {"offset": args.offset_ms, "readout": args.readout_ms, "rotation": args.rotation_deg,
                  "bias": args.bias_mrad_s}
    print(f"{len(rows)} bags from {', '.join(args.csv)}; covered/counted, median reported 1-sigma")
    if args.grid:
        for quantity, values in GRID.items():
            print(quantity)
            for factor in (1.0, 1.5, 2.0, 2.5, 3.0):
                cells = []
                for value in values:
                    c, n, m = coverage(pairs(rows, quantity), factor, value)
                    cells.append(f"{value:g}: {c}/{n} ({100.0 * c / max(n, 1):.0f} %) {m:.3f}")
                print(f"  factor {factor:g} | " + " | ".join(cells))
        return
    print(f"factor {args.factor:g}, systematic {systematic}")
    for label, subset in kinds:
        cells = []
        for quantity in QUANTITIES:
            c, n, m = coverage(pairs(subset, quantity), args.factor, systematic[quantity])
            cells.append(f"{quantity} {c}/{n}, {m:.3f} {QUANTITIES[quantity][2]}")
        covered_bags = 0
        for row in subset:
            errors, sigmas, _ = QUANTITIES["rotation"]
            covered_bags += all(
                abs(float(row[e])) <= math.hypot(args.factor * float(row[s]), args.rotation_deg)
                for e, s in zip(errors, sigmas))
        print(f"  {label}: " + "; ".join(cells) + f"; rotation all 3 axes {covered_bags}/{len(subset)} bags")


if __name__ == "__main__":
    main()
