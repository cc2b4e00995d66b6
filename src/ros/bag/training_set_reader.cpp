#include "deep_ois/ros/bag/training_set_reader.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <stdexcept>

#include "deep_ois/TrainingPair.h"
#include "deep_ois/ros/messages/conversions.h"

namespace deep_ois {

TrainingSet readTrainingSet(const std::vector<std::string>& bags, const std::string& topic) {
  TrainingSet set;
  for (const std::string& path : bags) {
    std::size_t records_in_bag = 0;
    try {
      rosbag::Bag bag(path, rosbag::bagmode::Read);
      rosbag::View view(bag, rosbag::TopicQuery(topic));
      for (const rosbag::MessageInstance& instance : view) {
        const TrainingPair::ConstPtr record = instance.instantiate<TrainingPair>();
        if (!record) throw std::runtime_error("a message on " + topic + " is not a deep_ois/TrainingPair");
        ++records_in_bag;
        ++set.records;
        if (!record->accepted) ++set.skipped_by_reason["rejected by the job: " + record->rejection_reason];
        if (record->gyro_homographies.empty()) continue;  // no gyro input: the history restarts after it
        TrainingSample sample;
        sample.gyro_homographies = unflattenMatrices(record->gyro_homographies);
        if (record->accepted) sample.target_homographies = unflattenMatrices(record->target_homographies);
        const std::size_t patches = record->patch_count;
        if (patches == 0 || sample.gyro_homographies.size() != patches ||
            (record->accepted && sample.target_homographies.size() != patches)) {
          ++set.skipped_by_reason["malformed: homography counts differ from patch_count"];
          continue;
        }
        sample.camera = CameraModel(static_cast<int>(record->image_width), static_cast<int>(record->image_height),
                                    rowMajorToMatrix(record->K.data()),
                                    record->distortion_model == "plumb_bob" ? record->D : std::vector<double>{});
        const std::string problem = sample.camera.validate();
        if (!problem.empty()) {
          ++set.skipped_by_reason["malformed camera: " + problem];
          continue;
        }
        sample.source = record->source_bag;
        sample.stamp_a_ns = static_cast<std::int64_t>(record->previous_stamp.toNSec());
        sample.stamp_b_ns = static_cast<std::int64_t>(record->header.stamp.toNSec());
        if (sample.hasTarget()) ++set.with_target;
        set.samples.push_back(std::move(sample));
      }
    } catch (const rosbag::BagException& e) {
      throw std::runtime_error(path + ": " + e.what());
    }
    if (records_in_bag == 0) {
      throw std::runtime_error(path + ": no deep_ois/TrainingPair on " + topic +
                               " (is it a training set written by the fundamental_mixtures job?)");
    }
  }
  return set;
}

}  // namespace deep_ois
