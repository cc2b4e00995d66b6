// The stages of the stabiliser model in the chain's (and the file's) order.
#include <stdexcept>

#include "deep_ois/core/ois/stabiliser_stage.h"

namespace deep_ois {

const std::vector<StabiliserStage>& stabiliserStages() {
  static const std::vector<StabiliserStage> stages = {
      centringStage(),          actuatorStage(),        strokeStage(),
      excursionCentringStage(), actuatorCouplingStage(), panDetectionStage(),
      linearResidualStage(),    learnedResidualStage(), learnedLensDynamicsStage()};
  return stages;
}

const FittedStabiliserParameter& fittedStabiliserParameter(const std::string& name) {
  for (const StabiliserStage& stage : stabiliserStages())
    for (const FittedStabiliserParameter& parameter : stage.fitted)
      if (name == parameter.name) return parameter;
  throw std::invalid_argument("no fitted stabiliser parameter named '" + name + "'");
}

}  // namespace deep_ois
