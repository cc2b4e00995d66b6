#include "deep_ois/tools/support/stabiliser_oracle_row.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>

#include "deep_ois/core/ois/lens_shift_homographies.h"
#include "deep_ois/core/ois/stabiliser_compensator.h"
#include "deep_ois/core/sim/stabiliser_oracle.h"

namespace deep_ois {

AlignmentMethod stabiliserOracleMethod(const std::string& name, const sim::SimulatorConfig& design,
                                       double start_before_first_frame_s, unsigned scope) {
  struct Stream {
    std::unique_ptr<sim::StabiliserOracle> oracle;
    std::string error;  // why this recording has no oracle
    std::uint64_t recording = std::numeric_limits<std::uint64_t>::max();
  };
  auto stream = std::make_shared<Stream>();
  return {name, scope, [stream, design, start_before_first_frame_s](const FramePairContext& pair) {
            if (!pair.imu || !pair.rolling_shutter || !pair.camera ||
                pair.gyro_rotations.empty()) {
              return AlignmentEstimate::failed("no gyro stream for the stabiliser oracle");
            }
            const RollingShutterConfig& rs = *pair.rolling_shutter;
            if (pair.recording_id != stream->recording) {
              // The whole recording's gyro at once, from the stabiliser's start (IMU clock).
              stream->recording = pair.recording_id;
              stream->oracle.reset();
              stream->error.clear();
              if (pair.camera->width() != design.sensor.width_px ||
                  pair.camera->height() != design.sensor.height_px) {
                stream->error = "the recording's camera is " + std::to_string(pair.camera->width()) +
                                "x" + std::to_string(pair.camera->height()) +
                                ", the oracle's design is for " +
                                std::to_string(design.sensor.width_px) + "x" +
                                std::to_string(design.sensor.height_px);
              } else {
                try {
                  stream->oracle = std::make_unique<sim::StabiliserOracle>(
                      design.ois, pair.camera->K()(0, 0),
                      cameraRates(*pair.imu, rs.imu_to_camera_rotation,
                                  -std::numeric_limits<double>::infinity(),
                                  std::numeric_limits<double>::infinity()),
                      std::isnan(start_before_first_frame_s)
                          ? start_before_first_frame_s
                          : pair.stamp_a_s + rs.time_offset_s - start_before_first_frame_s);
                } catch (const std::invalid_argument& e) {
                  stream->error = e.what();
                }
              }
            }
            if (!stream->oracle) return AlignmentEstimate::failed(stream->error);
            std::vector<Eigen::Vector2d> shift_a, shift_b;
            for (int i = 0; i < rs.patch_count; ++i) {
              const double t_a = patchImuTime(rs, pair.stamp_a_s, i);
              const double t_b = patchImuTime(rs, pair.stamp_b_s, i);
              if (!stream->oracle->covers(t_a) || !stream->oracle->covers(t_b)) {
                return AlignmentEstimate::failed("the gyro stream does not cover the pair");
              }
              shift_a.push_back(stream->oracle->lensShift(t_a));
              shift_b.push_back(stream->oracle->lensShift(t_b));
            }
            return AlignmentEstimate::patchHomographies(
                lensShiftHomographies(pair.camera->K(), pair.gyro_rotations, shift_a, shift_b));
          }};
}

}  // namespace deep_ois
