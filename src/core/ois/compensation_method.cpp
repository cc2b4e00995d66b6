#include "deep_ois/core/ois/compensation_method.h"

#include "deep_ois/core/ois/stabiliser_model_file.h"

namespace deep_ois {

CompensatorKind compensatorKindFor(const std::string& model_path) {
  return isStabiliserModelPath(model_path) ? CompensatorKind::kStabiliserModel : CompensatorKind::kNetwork;
}

CompensationMethod compensationMethodFor(CompensatorKind kind, bool flow_includes_lens_log) {
  if (flow_includes_lens_log) return CompensationMethod::kAsMeasured;
  return kind == CompensatorKind::kStabiliserModel ? CompensationMethod::kStabiliserModel
                                                   : CompensationMethod::kNetwork;
}

bool methodUsesModel(CompensationMethod method) { return method != CompensationMethod::kAsMeasured; }

bool publishesPlainGyro(CompensationMethod method, bool checks_fall_back) {
  return method == CompensationMethod::kStabiliserModel && checks_fall_back;
}

const char* toString(CompensationMethod method) {
  switch (method) {
    case CompensationMethod::kAsMeasured:
      return "as measured (lens-shift log)";
    case CompensationMethod::kNetwork:
      return "network";
    case CompensationMethod::kStabiliserModel:
      return "stabiliser model";
  }
  return "unknown";
}

}  // namespace deep_ois
