#!/usr/bin/python3
"""Makes a recording's IMU clock drift against its camera clock, for a soak with a drifting clock.

The IMU stamps of RECORDING (a simulated bag: its true offset is its config's imu.time_offset_s,
0 for config/simulator/RE.yaml) are moved by

    drift(t) = amplitude * sin(2 pi (t - t0) / period)

with t the stamp, t0 the first camera frame's stamp and period the recording's length (last frame
minus first plus one frame interval), so that a looped replay (`rosbag play --loop`) has no jump in
the offset where it starts over. The drift's steepest slope is 2 pi amplitude / period; the
amplitude is chosen from it (--peak-drift-ms-per-min, 3 as benchmark_online_calibration's drift).
The true offset at camera stamp t is then base + drift(t): written to OUT.truth.yaml for the soak's
comparison. Only the topics a live replay plays are copied (the IMU, the camera and its
camera_info, tf_static); the others (the lens-shift log, the ground truth) are left out.

    drifting_clock_bag.py RECORDING OUT [--peak-drift-ms-per-min 3] [--base-offset 0]
"""
import argparse
import math
import sys

import rosbag

TOPICS = ["/imu/data", "/camera/image_raw", "/camera/camera_info", "/tf_static"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording")
    parser.add_argument("out")
    parser.add_argument("--peak-drift-ms-per-min", type=float, default=3.0,
                        help="the drift's steepest slope, ms of offset per minute (default 3)")
    parser.add_argument("--base-offset", type=float, default=0.0,
                        help="the recording's own offset, seconds (its config's imu.time_offset_s; default 0)")
    args = parser.parse_args()
    if not args.peak_drift_ms_per_min > 0.0:
        sys.exit("drifting_clock_bag.py: --peak-drift-ms-per-min must be positive")

    with rosbag.Bag(args.recording) as bag:
        frames = [m.header.stamp.to_sec() for _, m, _ in bag.read_messages(topics=["/camera/camera_info"])]
    if len(frames) < 2:
        sys.exit("drifting_clock_bag.py: %s has fewer than 2 frames on /camera/camera_info" % args.recording)
    t0 = frames[0]
    period_s = frames[-1] - frames[0] + (frames[-1] - frames[0]) / (len(frames) - 1)
    rate = args.peak_drift_ms_per_min * 1e-3 / 60.0
    amplitude_s = rate * period_s / (2.0 * math.pi)

    imu = 0
    with rosbag.Bag(args.recording) as bag, rosbag.Bag(args.out, "w", compression="lz4") as out:
        for topic, msg, t in bag.read_messages(topics=TOPICS):
            if topic == "/imu/data":
                stamp = msg.header.stamp.to_sec()
                msg.header.stamp = msg.header.stamp.from_sec(
                    stamp + amplitude_s * math.sin(2.0 * math.pi * (stamp - t0) / period_s))
                imu += 1
            out.write(topic, msg, t)
    with open(args.out + ".truth.yaml", "w") as truth:
        truth.write("# IMU time = camera stamp t + base + amplitude * sin(2 pi (t - t0) / period) (seconds)\n")
        truth.write("base: %.9f\namplitude: %.9f\nt0: %.9f\nperiod: %.9f\n" % (args.base_offset, amplitude_s, t0, period_s))
    print("%s: %d IMU stamps moved by a drift of %.3f ms amplitude over a %.1f s period (steepest %.2f ms/min); "
          "truth in %s.truth.yaml" % (args.out, imu, amplitude_s * 1e3, period_s, args.peak_drift_ms_per_min, args.out))


if __name__ == "__main__":
    main()
