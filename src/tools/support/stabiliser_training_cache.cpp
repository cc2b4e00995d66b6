#include "deep_ois/tools/support/stabiliser_training_cache.h"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "deep_ois/tools/support/dataset_hash.h"

namespace deep_ois {
namespace {

namespace fs = std::filesystem;

// The code that computes the data: bump when the ground truth, the log reading or this file's
// format changes, so that caches of the old code are recomputed. 2: keyed on content and config,
// observations carry their readout fraction.
constexpr int kCacheVersion = 2;
constexpr char kMagic[] = "deep_ois_stabiliser_cache";

// 12 significant digits: exact for any value a config file holds, readable in a message.
std::string text(double value) {
  std::ostringstream out;
  out.precision(12);
  out << value;
  return out.str();
}

}  // namespace

StabiliserCacheKey stabiliserCacheKey(const std::string& bag, const GyroFlowParameters& gyro,
                                      const std::string& target) {
  const RollingShutterConfig& rs = gyro.rolling_shutter;
  const LensShiftLogConvention& log = gyro.lens_shift_convention;
  StabiliserCacheKey key = {
      {"code", std::to_string(kCacheVersion)},
      {"bag_sha256", sha256OfFiles({bag})},
      {"target", target},
      {"readout_time", text(rs.readout_time_s)},
      {"time_offset", text(rs.time_offset_s)},
      {"patch_count", std::to_string(rs.patch_count)},
      {"patch_time", rs.patch_time == PatchTimeReference::kPatchCentre ? "centre" : "start"},
      {"rate_interpolation", std::to_string(static_cast<int>(gyro.integration.interpolation))},
      {"gyro_bias", text(gyro.integration.gyro_bias_rad_s.x()) + " " +
                        text(gyro.integration.gyro_bias_rad_s.y()) + " " +
                        text(gyro.integration.gyro_bias_rad_s.z())},
      {"max_sample_gap", text(gyro.integration.max_sample_gap_s)},
      {"lens_shift_scale", text(log.scale)},
      {"lens_shift_swap_xy", log.swap_xy ? "true" : "false"},
      {"lens_shift_sign", text(log.sign_x) + " " + text(log.sign_y)},
      {"lens_shift_time_offset", text(log.time_offset_s)},
      {"lens_shift_max_gap", text(gyro.lens_shift_max_gap_s)},
  };
  // The rotation from the config only when it is used (otherwise the bag's tf, hashed above).
  std::string rotation = "tf";
  if (!gyro.rotation_from_tf) {
    rotation.clear();
    for (int k = 0; k < 9; ++k)
      rotation += (k ? " " : "") + text(rs.imu_to_camera_rotation(k / 3, k % 3));
  }
  key.emplace_back("imu_to_camera_rotation", rotation);
  return key;
}

std::string stabiliserCachePath(const std::string& cache_dir, const std::string& bag,
                                const std::string& target) {
  std::string name = fs::absolute(bag).lexically_normal().string();
  for (char& c : name) {
    if (c == '/') c = '_';
  }
  return cache_dir + "/" + name + "." + target + ".txt";
}

void writeStabiliserCache(const std::string& path, const StabiliserCacheKey& key,
                          const std::string& bag, const StabiliserRecordingData& data) {
  const std::string partial = path + ".partial";
  {
    std::ofstream out(partial);
    out.precision(17);
    out << kMagic << " " << kCacheVersion << "\n";
    for (const auto& [name, value] : key) out << "key " << name << " " << value << "\n";
    out << "bag " << bag << "\n";
    const auto& c = data.camera;
    out << "camera " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx
        << " " << c.cy << " " << c.readout_time_s << " " << c.frame_rate_hz << "\n";
    out << "counts " << data.frame_pairs << " " << data.pairs_without_gyro << " "
        << data.pairs_without_tracks << " " << data.pairs_without_log << " "
        << data.median_track_residual_px << "\n";
    out << "recorded_readout " << data.recorded_readout_time_s << "\n";
    out << "focal " << data.recording.focal_px << "\n";
    for (const auto& r : data.recording.rates)
      out << "r " << r.stamp_s << " " << r.rate_rad_s.x() << " " << r.rate_rad_s.y() << " "
          << r.rate_rad_s.z() << "\n";
    for (const auto& o : data.recording.observations)
      out << "o " << o.t_a_s << " " << o.t_b_s << " " << o.motion_px.x() << " " << o.motion_px.y()
          << " " << o.weight << " " << o.readout_fraction << "\n";
    out << "end\n";
    if (!out) throw std::runtime_error(partial + ": write failed");
  }
  fs::rename(partial, path);  // complete files only
}

std::optional<StabiliserRecordingData> readStabiliserCache(const std::string& path,
                                                           const StabiliserCacheKey& key,
                                                           const std::string& bag,
                                                           std::string* why_not) {
  auto refuse = [&](const std::string& why) {
    if (why_not) *why_not = why;
    return std::nullopt;
  };
  std::ifstream in(path);
  if (!in) return refuse("no cache");
  StabiliserRecordingData data;
  data.recording.name = bag;
  std::string word, line;
  int version = 0;
  if (!(in >> word >> version) || word != kMagic) return refuse("not a cache file");
  if (version != kCacheVersion) return refuse("made by another version of the code");
  std::size_t next_key = 0;
  bool complete = false;
  while (in >> word) {
    if (word == "key") {
      std::string name, value;
      in >> name;
      std::getline(in, value);
      if (!value.empty() && value.front() == ' ') value.erase(0, 1);
      if (next_key >= key.size() || key[next_key].first != name)
        return refuse("made with other settings (" + name + ")");
      if (key[next_key].second != value) {
        if (name == "bag_sha256") return refuse("the bag's content changed");
        return refuse(name + " changed (" + value + " -> " + key[next_key].second + ")");
      }
      ++next_key;
    } else if (word == "bag") {
      std::getline(in, line);
    } else if (word == "camera") {
      auto& c = data.camera;
      in >> c.width >> c.height >> c.fx >> c.fy >> c.cx >> c.cy >> c.readout_time_s >>
          c.frame_rate_hz;
    } else if (word == "counts") {
      in >> data.frame_pairs >> data.pairs_without_gyro >> data.pairs_without_tracks >>
          data.pairs_without_log >> data.median_track_residual_px;
    } else if (word == "recorded_readout") {
      in >> data.recorded_readout_time_s;
    } else if (word == "focal") {
      in >> data.recording.focal_px;
    } else if (word == "r") {
      CameraRateSample r;
      in >> r.stamp_s >> r.rate_rad_s.x() >> r.rate_rad_s.y() >> r.rate_rad_s.z();
      data.recording.rates.push_back(r);
    } else if (word == "o") {
      LensMotionObservation o;
      in >> o.t_a_s >> o.t_b_s >> o.motion_px.x() >> o.motion_px.y() >> o.weight >>
          o.readout_fraction;
      data.recording.observations.push_back(o);
    } else if (word == "end") {
      complete = true;
      break;
    } else {
      return refuse("unreadable (\"" + word + "\")");
    }
    if (!in) return refuse("unreadable");
  }
  if (!complete) return refuse("incomplete");
  if (next_key != key.size())
    return refuse("made with other settings (" + key[next_key].first + ")");
  return data;
}

}  // namespace deep_ois
