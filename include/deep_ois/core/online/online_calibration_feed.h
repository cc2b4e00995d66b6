// The online calibration fed from the online learner's pairs: a pair the learner tracked (its
// stamps on the camera clock, its tracks, and the gyro behind it as the gyro flow sent it, rotated
// into the camera frame with the rotation in use) becomes the estimator's pair and raw IMU samples
// (rotated back with that rotation: the gyro flow rotates raw samples, it does not remove the bias).
// Install it as OnlineLearningOptions::on_tracked_pair, so that it runs on the learner's tracking
// thread within the learning's CPU budget:
//
//   options.on_tracked_pair = [&estimator](const OnlineFramePair& pair) { feedTrackedPair(pair, estimator); };
//
// Pure Eigen: no ROS.
#pragma once

#include "deep_ois/core/online/online_calibration_estimator.h"
#include "deep_ois/core/online/online_stabiliser_learner.h"

namespace deep_ois {

// Adds the pair's gyro (IMU clock, raw = R_cam_imu^T camera rate, R from pair.timing) and tracks to
// `estimator`, then runs its due work (update()). Returns whether the calibration in use changed.
// An untracked pair or one without gyro adds nothing but time.
bool feedTrackedPair(const OnlineFramePair& pair, OnlineCalibrationEstimator& estimator);

}  // namespace deep_ois
