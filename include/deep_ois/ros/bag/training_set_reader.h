// Reads the training-set bags of the offline Fundamental Mixtures job (deep_ois/TrainingPair
// records) into plain samples for the trainer.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "deep_ois/core/ground_truth/training_sample.h"

namespace deep_ois {

struct TrainingSet {
  // Records with a gyro input, in file order: the accepted ones with their target, the rejected
  // ones without (they only carry the motion history on to the next pair).
  std::vector<TrainingSample> samples;
  std::size_t records = 0;       // every record read
  std::size_t with_target = 0;   // samples with a target
  // Records without a target, by reason (the job's rejection reason, or what is malformed); the
  // rejected ones with a gyro input are still in `samples`.
  std::map<std::string, std::size_t> skipped_by_reason;
};

// Throws std::runtime_error naming the bag when one cannot be read or holds no record on `topic`.
TrainingSet readTrainingSet(const std::vector<std::string>& bags,
                            const std::string& topic = "/deep_ois/training_pair");

}  // namespace deep_ois
