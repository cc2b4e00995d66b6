#!/usr/bin/python3
"""The drifting-clock soak's report (scripts/soak.sh --drifting-clock): the calibration in use
against the true offset, the swaps, and the files persisted.

    soak_clock_report.py RECORD.bag TRUTH.yaml ROS_HOME [--skip-s 60]

RECORD.bag holds /deep_ois/online_calibration (latched, one message per change) and /diagnostics,
recorded through the soak. TRUTH.yaml is drifting_clock_bag.py's: the true offset at camera stamp t
is base + amplitude * sin(2 pi (t - t0) / period).

The calibration in use is the last message's line (time_offset + time_offset_rate * (t -
time_offset_reference), as the gyro flow nodelet applies it), evaluated every 0.1 s of camera time
from its message's stamp (the newest pair the estimator had) to the next message's. A bag loop
(the next stamp earlier) ends the span at the recording's end. The first --skip-s seconds of the
soak (record time) are left out of the verdict, as the target says ("after the first minute").
"""
import argparse
import math
import os
import sys

import rosbag


def read_truth(path):
    values = {}
    with open(path) as f:
        for line in f:
            line = line.split("#")[0].strip()
            if ":" in line:
                key, value = line.split(":", 1)
                values[key.strip()] = float(value)
    return values


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("record")
    parser.add_argument("truth")
    parser.add_argument("ros_home")
    parser.add_argument("--skip-s", type=float, default=60.0)
    args = parser.parse_args()
    truth = read_truth(args.truth)
    loop_end = truth["t0"] + truth["period"]

    def true_offset(t):
        return truth["base"] + truth["amplitude"] * math.sin(2.0 * math.pi * (t - truth["t0"]) / truth["period"])

    calibrations, diagnostics = [], {}
    with rosbag.Bag(args.record) as bag:
        for topic, msg, t in bag.read_messages(topics=["/deep_ois/online_calibration", "/diagnostics"]):
            if topic == "/deep_ois/online_calibration":
                calibrations.append((t.to_sec(), msg))
            else:
                for status in msg.status:
                    if "compensation" in status.name:
                        for kv in status.values:
                            diagnostics[kv.key] = kv.value
    if not calibrations:
        sys.exit("soak_clock_report: no online_calibration message in %s" % args.record)
    start = calibrations[0][0]
    per_minute = {}  # minute -> (worst error s, spans, evaluations)
    worst_after = 0.0
    evaluations_after = 0
    within_after = 0
    for i, (received, msg) in enumerate(calibrations):
        begin = msg.header.stamp.to_sec()
        end = calibrations[i + 1][1].header.stamp.to_sec() if i + 1 < len(calibrations) else begin + 1.5
        if end < begin:
            end = loop_end  # the bag looped: this line was in use to the recording's end
        reference = msg.time_offset_reference.to_sec()
        t = begin
        while t <= end:
            elapsed = t - reference
            applied = msg.time_offset if (msg.time_offset_rate == 0.0 or elapsed < -1.0) else \
                msg.time_offset + msg.time_offset_rate * elapsed
            error = abs(applied - true_offset(t))
            minute = int((received - start) // 60.0)
            worst, spans, count = per_minute.get(minute, (0.0, 0, 0))
            per_minute[minute] = (max(worst, error), spans, count + 1)
            if received - start >= args.skip_s:
                worst_after = max(worst_after, error)
                evaluations_after += 1
                within_after += error <= 0.5e-3
            t += 0.1
        worst, spans, count = per_minute.get(int((received - start) // 60.0), (0.0, 0, 0))
        per_minute[int((received - start) // 60.0)] = (worst, spans + 1, count)

    print("calibration in use against the drifting truth (amplitude %.3f ms, period %.1f s, steepest %.2f ms/min):"
          % (truth["amplitude"] * 1e3, truth["period"], 2 * math.pi * truth["amplitude"] / truth["period"] * 6e4))
    print("| minute | messages | worst error (ms) |")
    print("|---|---|---|")
    for minute in sorted(per_minute):
        worst, spans, _ = per_minute[minute]
        print("| %d | %d | %.3f |" % (minute + 1, spans, worst * 1e3))
    print("after the first %.0f s: worst %.3f ms; %d of %d evaluations (every 0.1 s of camera time) within 0.5 ms"
          % (args.skip_s, worst_after * 1e3, within_after, evaluations_after))
    last = calibrations[-1][1]
    print("online calibration, last message: version %d, state %s, %d pairs, %d fits (%d needing motion, %d "
          "rejected), %d jumps, %d swaps (%d undone by the per-pair check, %d confirmed)"
          % (last.version, last.state, last.pairs, last.fits, last.fits_needing_motion, last.fits_rejected,
             last.jumps, last.swaps, last.swaps_undone, last.swaps_confirmed))
    for key in ("model in use", "learning data", "learning: swap confirmation", "online calibration: counts",
                "online calibration CPU", "learning CPU", "online calibration: used by the gyro flow"):
        if key in diagnostics:
            print("diagnostics, %s: %s" % (key, diagnostics[key]))
    print("files persisted under %s:" % args.ros_home)
    found = False
    for root, _, files in os.walk(args.ros_home):
        for name in sorted(files):
            if name.endswith(".yaml"):
                path = os.path.join(root, name)
                print("  %s (%d bytes)" % (os.path.relpath(path, args.ros_home), os.path.getsize(path)))
                found = True
    if not found:
        print("  none")


if __name__ == "__main__":
    main()
