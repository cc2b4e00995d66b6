#include "deep_ois/core/evaluation/stabiliser_table_row.h"

#include <cstdint>
#include <limits>
#include <memory>

#include "deep_ois/core/ois/stabiliser_compensator.h"

namespace deep_ois {

AlignmentMethod stabiliserAlignmentMethod(const std::string& name,
                                          const StabiliserParameters& parameters, unsigned scope) {
  struct Stream {
    std::unique_ptr<StabiliserCompensator> compensator;
    std::uint64_t recording = std::numeric_limits<std::uint64_t>::max();
  };
  auto stream = std::make_shared<Stream>();
  return {name, scope, [stream, parameters](const FramePairContext& pair) {
            if (!pair.imu || !pair.rolling_shutter || !pair.camera ||
                pair.gyro_rotations.empty()) {
              return AlignmentEstimate::failed("no gyro stream for the stabiliser model");
            }
            if (!stream->compensator || pair.recording_id != stream->recording) {
              stream->compensator =
                  std::make_unique<StabiliserCompensator>(parameters, pair.camera->K());
              stream->recording = pair.recording_id;
            }
            const RollingShutterConfig& rs = *pair.rolling_shutter;
            std::vector<double> times_a, times_b;
            for (int i = 0; i < rs.patch_count; ++i) {
              times_a.push_back(patchImuTime(rs, pair.stamp_a_s, i));
              times_b.push_back(patchImuTime(rs, pair.stamp_b_s, i));
            }
            StabiliserCompensator& compensator = *stream->compensator;
            compensator.addRates(cameraRates(*pair.imu, rs.imu_to_camera_rotation,
                                             compensator.feedFrom(times_a.front()),
                                             times_b.back()));
            const StabiliserCompensation result =
                compensator.compensate(pair.gyro_rotations, times_a, times_b);
            if (!result.ok) return AlignmentEstimate::failed(result.reason);
            return AlignmentEstimate::patchHomographies(result.homographies);
          }};
}

}  // namespace deep_ois
