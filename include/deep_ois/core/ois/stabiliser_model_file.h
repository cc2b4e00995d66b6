// A learned stabiliser model as a file (YAML, readable and diffable): the parameters, the camera
// it was trained for and the data it was trained on. The compensation nodelet, the evaluator and
// the trainer read and write it through this one type.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/core/camera/camera_description.h"
#include "deep_ois/core/ois/stabiliser_model.h"

namespace deep_ois {

// A file that is missing, unreadable or not a stabiliser model: what() names the file and field.
class StabiliserModelFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct StabiliserTrainingRecord {
  std::string target;  // what the lens motion came from: "gyro-anchored lens shift", "lens log"
  std::vector<std::string> data_files;
  std::string data_sha256;  // of the data files' bytes in order (`cat files | sha256sum`)
  std::size_t recordings = 0;
  std::size_t observations = 0;  // lens motions (pairs x row patches) fitted
  // RMS lens-motion residual (pixels): without a lens model (what the uncompensated gyro assumes)
  // and with the fitted model; on the training data and on held-out recordings (NaN when none).
  double rms_without_model_px = 0.0;
  double rms_px = 0.0;
  double held_out_rms_without_model_px = 0.0;
  double held_out_rms_px = 0.0;
  double training_time_s = 0.0;
};

struct StabiliserModelFile {
  static constexpr int kFormatVersion = 1;
  int format_version = kFormatVersion;
  std::string name;  // e.g. "generic (10 simulated modules)" or the user's camera
  StabiliserModel parameters;
  CameraDescription camera;
  StabiliserTrainingRecord training;

  std::string toYaml() const;
  // Throws StabiliserModelFileError naming the missing or malformed field.
  static StabiliserModelFile fromYaml(const std::string& yaml_text);
  static StabiliserModelFile load(const std::string& path);  // errors name the file
  // Atomic (written beside `path`, then renamed). Errors name the file and, when it cannot be
  // created, its folder (missing, not a folder or not writable) and the system's reason.
  void save(const std::string& path) const;
  // Throws the error save() would throw for a missing or unwritable folder, without writing the
  // model: tools call it before a long fit, so a mistyped --out does not cost the fit.
  static void checkSavable(const std::string& path);
};

// Whether a path names a stabiliser model (.yaml) rather than a network (.pt).
bool isStabiliserModelPath(const std::string& path);

}  // namespace deep_ois
