#include "deep_ois/core/evaluation/stabiliser_table_row.h"

#include <cstdint>
#include <limits>
#include <memory>

#include "deep_ois/core/pipeline/frame_pair_processor.h"

namespace deep_ois {

AlignmentMethod stabiliserAlignmentMethod(const std::string& name,
                                          const StabiliserModel& parameters, unsigned scope) {
  struct Stream {
    std::unique_ptr<FramePairProcessor> processor;
    std::uint64_t recording = std::numeric_limits<std::uint64_t>::max();
  };
  auto stream = std::make_shared<Stream>();
  return {name, scope, [stream, parameters](const FramePairContext& pair) {
            if (!pair.imu || !pair.rolling_shutter || !pair.camera ||
                pair.gyro_rotations.empty()) {
              return AlignmentEstimate::failed("no gyro stream for the stabiliser model");
            }
            // One stabiliser state per recording, fed in pair order: the evaluator's pairs come
            // in recording order and never loop, so the timeline is not followed.
            if (!stream->processor || pair.recording_id != stream->recording) {
              stream->processor = std::make_unique<FramePairProcessor>(
                  parameters, FramePairProcessor::Timeline::kPairsInOrder);
              stream->recording = pair.recording_id;
            }
            FramePair input;
            input.stamp_a_s = pair.stamp_a_s;
            input.stamp_b_s = pair.stamp_b_s;
            input.timing = *pair.rolling_shutter;
            input.camera = pair.camera;
            input.rotations = pair.gyro_rotations;
            input.gyro_homographies = pair.gyro_homographies;
            input.imu = pair.imu;
            const FramePairMotion motion = stream->processor->process(std::move(input));
            if (!motion.ok) return AlignmentEstimate::failed(motion.reason);
            return AlignmentEstimate::patchHomographies(motion.homographies);
          }};
}

}  // namespace deep_ois
