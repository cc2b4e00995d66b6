// The simulated 3D scene: textured planes at several depths, built from real photographs.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "deep_ois/core/sim/camera_motion.h"

namespace deep_ois {
namespace sim {

// The paper's evaluation categories.
enum class Category {
  kRegular,           // RE: rich texture
  kLowTexture,        // LT: large sky / wall areas with almost no texture
  kLowLight,          // LL: dark scene (the sensor adds shot and read noise, longer exposure)
  kMovingForeground,  // MF: a textured object moving on its own over >= 20 % of the frame
};
const char* toString(Category category);          // "RE", "LT", "LL", "MF"
bool parseCategory(const std::string& text, Category* category);

// A rectangle in the world carrying a texture. Point (u, v) in [0, width] x [0, height] metres is
// at origin + u * axis_u + v * axis_v (+ velocity * t for a moving plane); texture pixel (0, 0)
// is at (u, v) = (0, 0), x along axis_u.
struct TexturedPlane {
  Eigen::Vector3d origin_world_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_u = Eigen::Vector3d::UnitY();  // unit vector
  Eigen::Vector3d axis_v = -Eigen::Vector3d::UnitZ();  // unit vector, orthogonal to axis_u
  double width_m = 1.0;
  double height_m = 1.0;
  // Linear radiance in [0, 1], CV_32FC3 RGB, pre-filtered for the size it appears at on screen
  // (texel about half a supersample at the plane's depth), so sampling it does not alias.
  cv::Mat texture;
  Eigen::Vector3d velocity_world_m_s = Eigen::Vector3d::Zero();  // non-zero: a moving object
  bool isStatic() const { return velocity_world_m_s.isZero(0.0); }
};

struct SceneConfig {
  // Photographs used as textures (any format cv::imread reads). Default: the nature set of
  // Debian's mate-backgrounds package (installed by scripts/install_deps.sh).
  std::vector<std::string> texture_paths;
  int near_layer_count = 3;  // textured planes between the camera and the background
  double near_depth_min_m = 1.5;
  double near_depth_max_m = 5.0;
  double background_depth_min_m = 10.0;
  double background_depth_max_m = 50.0;
  double low_texture_fraction = 0.6;         // LT: share of the view that is sky / plain wall
  double moving_object_depth_m = 2.0;        // MF
  double moving_object_speed_m_s = 0.4;      // MF: speed of its own motion
  double moving_object_min_coverage = 0.25;  // MF: fraction of the frame it covers (>= 0.2)

  std::string validate() const;  // empty, or a sentence naming the bad field
};

// A ray hit: where, on what, and its colour.
struct SceneHit {
  double distance_m = 0.0;  // along the (unit) ray direction
  int plane_index = -1;
  bool is_static = true;
  Eigen::Vector3d point_world_m = Eigen::Vector3d::Zero();
  Eigen::Vector3f radiance = Eigen::Vector3f::Zero();  // linear RGB, bilinear texture sample
};

class Scene {
 public:
  Scene() = default;
  explicit Scene(std::vector<TexturedPlane> planes);

  // Nearest plane hit by the ray origin + s * direction (s > 0, `direction` unit) at time t_s.
  // False when the ray hits nothing.
  bool intersect(const Eigen::Vector3d& origin_world_m, const Eigen::Vector3d& direction,
                 double t_s, SceneHit* hit) const;

  const std::vector<TexturedPlane>& planes() const { return planes_; }

 private:
  std::vector<TexturedPlane> planes_;
};

// Lays out a scene for a category in front of the camera (which looks along world +x at t=0 and
// moves as `motion` says), large enough to fill the view over the whole motion. `focal_px` and
// `supersampling` set the texture pre-filtering. Throws std::runtime_error naming a texture
// that cannot be read.
Scene buildScene(const SceneConfig& config, Category category, std::uint32_t seed,
                 const CameraMotion& motion, double focal_px, int supersampling);

// The default texture list (mate-backgrounds' nature photographs that exist on this machine).
std::vector<std::string> defaultTexturePaths();

}  // namespace sim
}  // namespace deep_ois
