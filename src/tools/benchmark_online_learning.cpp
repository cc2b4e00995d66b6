// The cold-start learning curve of the live pipeline's online self-calibration: long recordings of
// one camera replayed pair by pair through the compensation's stabiliser path with its online
// learner (core/online/online_stabiliser_learner.h, the class the compensation nodelet runs;
// its ROS wrapper only converts messages), starting from a given model (default: the shipped
// generic one) with nothing learned, and scored in the paper's metric per window of replay time
// against the uncompensated OIS gyro and the non-OIS twin (the gap closed) and the fixed model.
//
//   benchmark_online_learning --bags long_ois.bag --twins long_nonois.bag [--model MODEL.yaml]
//       [--window 10] [--cpu-share 0.3] [--plot curve.png]
//   benchmark_online_learning --bags ois_off.bag --no-ois      (a camera without OIS: vs the gyro)
//   benchmark_online_learning --bags long_ois.bag --twins long_nonois.bag --online-calibration
//       (the compensation nodelet's online camera-IMU calibration runs on the learner's tracks as it
//        does live (core/online/online_calibration_session.h), and its cost is printed beside the
//        learner's)
//   benchmark_online_learning --bags s1.bag s2.bag s3.bag --twins t1.bag t2.bag t3.bag --continue-bags
//       (one camera's session longer than one recording: the learner, its check and the replay
//        clock carry on, and the stamps of each next recording are shifted to follow the previous
//        one after --continue-gap seconds)
//
// Budget: the learner gets --cpu-share of one core in REPLAY time (the replay waits while the
// learner is over it), so the curve is the one a live camera at that budget would see, whatever
// the replay's own speed.
#include <ros/package.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "deep_ois/core/evaluation/stabiliser_table_row.h"
#include "deep_ois/core/evaluation/standard_table_rows.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/online/online_calibration_session.h"
#include "deep_ois/core/online/online_stabiliser_learner.h"
#include "deep_ois/core/pipeline/frame_pair_processor.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"
#include "deep_ois/ros/live/parameter_source.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/evaluation_runner.h"
#include "deep_ois/tools/support/csv_plot.h"

namespace {

constexpr const char* kOnlineMethod = "stabiliser, learning online";
constexpr const char* kFixedMethod = "stabiliser, the starting model (fixed)";

double threadCpuSeconds() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

// The compensation nodelet's online calibration (ros/live/online_calibration_ros.cpp) on the
// learner's tracking thread: the lens shifts the compensation used per pair (remembered by the
// output path, as rememberLens), the session made at the first tracked pair, its thread CPU time.
struct CalibrationRun {
  deep_ois::OnlineCalibrationOptions options;  // the nodelet's defaults (mount held, 12 % budget)
  std::size_t confirm_pairs = 60;              // ~learning_confirm_pairs
  Eigen::Vector3d start_bias_rad_s = Eigen::Vector3d::Zero();
  bool lens_moves = true;
  std::mutex mutex;                            // lenses, written by the output path
  std::deque<deep_ois::PairLensShift> lenses;  // the newest 120, as the nodelet keeps
  std::atomic<bool> time_went_back{false};
  // Tracking thread only.
  std::unique_ptr<deep_ois::OnlineCalibrationSession> session;
  double cpu_s = 0.0;
  std::size_t pairs = 0;
  std::string last_log, problem;

  void remember(deep_ois::PairLensShift lens) {
    std::lock_guard<std::mutex> lock(mutex);
    lenses.push_back(std::move(lens));
    while (lenses.size() > 120) lenses.pop_front();
  }
  // OnlineLearningOptions::on_tracked_pair: what OnlineCalibrationRos::onTrackedPair does.
  void onTrackedPair(const deep_ois::OnlineFramePair& pair) {
    const double started = threadCpuSeconds();
    try {
      if (!session) {
        deep_ois::CameraImuCalibration start;
        start.time_offset_s = pair.timing.time_offset_s;
        start.readout_time_s = pair.timing.readout_time_s;
        start.imu_to_camera_rotation = pair.timing.imu_to_camera_rotation;
        start.gyro_bias_rad_s = start_bias_rad_s;
        options.lens_shift = lens_moves ? deep_ois::LensShiftHandling::kPerFrameShift : deep_ois::LensShiftHandling::kNone;
        // Nothing is written: the confirmation's write is the nodelet's (an atomic file write).
        session = std::make_unique<deep_ois::OnlineCalibrationSession>(
            options, confirm_pairs, pair.camera, start, nullptr, "(not written by the benchmark)");
      }
      if (time_went_back.exchange(false)) session->restartTimeline();
      deep_ois::PairLensShift lens;
      bool found = false;
      {
        std::lock_guard<std::mutex> lock(mutex);
        const auto it = std::find_if(lenses.begin(), lenses.end(),
                                     [&](const deep_ois::PairLensShift& l) { return l.stamp_b_s == pair.stamp_b_s; });
        if (it != lenses.end()) {
          lens = *it;
          found = true;
        }
      }
      const auto outcome = session->addPair(deep_ois::lenslessPair(pair, found ? &lens : nullptr));
      if (!outcome.log.empty()) last_log = outcome.log;
      ++pairs;
    } catch (const std::exception& e) {
      problem = e.what();
    }
    cpu_s += threadCpuSeconds() - started;
  }
};

// The live path over the evaluator's pairs: the model in use (swapped when the learner swaps it),
// the fallback to the plain gyro, every pair handed to the learner with its frames.
struct OnlinePath {
  std::unique_ptr<deep_ois::OnlineStabiliserLearner> learner;
  std::unique_ptr<deep_ois::FramePairProcessor> processor;  // the compensation's stabiliser path
  std::uint64_t recording = ~std::uint64_t{0};
  std::uint64_t version = ~std::uint64_t{0};
  double cpu_share = 0.3;
  double replay_s = 0.0;        // replay time of the recordings before this one
  double recording_start_s = 0.0, last_stamp_s = 0.0;
  // --continue-bags: the next recording's stamps follow the previous one's after gap_s; the
  // learner sees them shifted by shift_s (the gyro flow and the compensator keep the bag's own).
  bool continue_bags = false;
  double gap_s = 1.0, shift_s = 0.0;
  std::vector<std::pair<double, std::string>> swaps;  // replay time, model
  std::size_t fallback_pairs = 0, pairs = 0;
  std::atomic<double> replay_clock_s{0.0};  // the learner's budget clock
  std::shared_ptr<CalibrationRun> calibration;  // --online-calibration, else null
  // Per pair, the output path's time (the compensator's step, the pair handed to the learner and the
  // fallback read), ms: what the compensation callback does besides the messages.
  std::vector<double> output_ms;
};

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return std::nan("");
  const auto k = static_cast<std::size_t>(std::min<double>(values.size() - 1, std::floor(q * values.size())));
  std::nth_element(values.begin(), values.begin() + static_cast<long>(k), values.end());
  return values[k];
}

deep_ois::AlignmentMethod onlineMethod(std::shared_ptr<OnlinePath> path, unsigned scope) {
  return {kOnlineMethod, scope, [path](const deep_ois::FramePairContext& pair) {
            using deep_ois::AlignmentEstimate;
            if (!pair.imu || !pair.rolling_shutter || !pair.camera || pair.gyro_rotations.empty())
              return AlignmentEstimate::failed("no gyro stream for the stabiliser model");
            const deep_ois::RollingShutterConfig& rs = *pair.rolling_shutter;
            OnlinePath& p = *path;
            const auto started = std::chrono::steady_clock::now();
            if (pair.recording_id != p.recording) {
              const bool first = p.recording == ~std::uint64_t{0};
              if (!first) p.replay_s += p.last_stamp_s - p.recording_start_s;
              if (p.continue_bags && !first) {
                // Time goes on: the learner's windows, buffer, check and fallback carry over.
                p.replay_s += p.gap_s;
                p.shift_s = p.last_stamp_s + p.shift_s + p.gap_s - pair.stamp_a_s;
              } else {
                p.learner->restartTimeline();
                if (p.calibration && !first) p.calibration->time_went_back = true;
              }
              p.recording = pair.recording_id;
              p.recording_start_s = pair.stamp_a_s;
              // The stabiliser's state starts again (another recording's lens).
              if (p.processor) p.processor->restart();
            }
            p.last_stamp_s = pair.stamp_b_s;
            const std::shared_ptr<const deep_ois::LearnedStabiliser> model = p.learner->model();
            if (!p.processor) {
              p.processor = std::make_unique<deep_ois::FramePairProcessor>(model->parameters);
              p.version = model->version;
            } else if (model->version != p.version) {
              if (p.version != ~std::uint64_t{0})
                p.swaps.push_back({p.replay_s + pair.stamp_b_s - p.recording_start_s, model->name});
              p.processor->setModel(model->parameters);
              p.version = model->version;
            }
            // As the compensation nodelet: the stabiliser's timeline followed, the gyro's motion
            // the gyro flow nodelet's.
            deep_ois::FramePair input;
            input.stamp_a_s = pair.stamp_a_s;
            input.stamp_b_s = pair.stamp_b_s;
            input.timing = rs;
            input.camera = pair.camera;
            input.rotations = pair.gyro_rotations;
            input.gyro_homographies = pair.gyro_homographies;
            input.imu = pair.imu;
            const deep_ois::FramePairMotion result = p.processor->process(std::move(input));
            if (!result.ok) return AlignmentEstimate::failed(result.reason);

            deep_ois::OnlineFramePair online;
            online.stamp_a_s = pair.stamp_a_s + p.shift_s;
            online.stamp_b_s = pair.stamp_b_s + p.shift_s;
            online.timing = rs;
            online.camera = *pair.camera;
            online.rotations = pair.gyro_rotations;
            online.gyro_homographies = pair.gyro_homographies;
            online.model_homographies = result.homographies;
            // The pair's gyro stream, as the GyroFlow message carries it to the learner live: from
            // kStabiliserWarmUpS before frame a's first patch to frame b's last patch (was a
            // hand-typed 1.1 s before frame b, about 70 ms more at 30 fps).
            online.rates = deep_ois::pairGyroStream(*pair.imu, rs, pair.stamp_a_s, pair.stamp_b_s);
            for (deep_ois::CameraRateSample& r : online.rates) r.stamp_s += p.shift_s;
            double output_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
            // The evaluator's frames live only during the call (the nodelet shares the messages'
            // instead): the copy is not part of the output path's time.
            online.image_a = pair.gray_a.clone();
            online.image_b = pair.gray_b.clone();
            // The learner's budget runs on replay time (its clock); the replay waits for its queue
            // (the replay's own speed is not the camera's), and the learner skips pairs over its
            // budget as it does live.
            p.replay_clock_s.store(p.replay_s + pair.stamp_b_s - p.recording_start_s);
            while (p.learner->queued() >= 10) std::this_thread::sleep_for(std::chrono::milliseconds(2));
            const auto handed = std::chrono::steady_clock::now();
            // As the nodelet's rememberLens, before the submit: the lens the output used for the pair.
            if (p.calibration && !p.learner->fallingBack() && !result.shift_a_px.empty() &&
                result.shift_a_px.size() == result.shift_b_px.size())
              p.calibration->remember({online.stamp_b_s, result.shift_a_px, result.shift_b_px});
            p.learner->submit(std::move(online));
            ++p.pairs;
            const bool falling_back = p.learner->fallingBack();
            output_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - handed).count();
            p.output_ms.push_back(1e3 * output_s);
            if (falling_back) {
              ++p.fallback_pairs;
              return AlignmentEstimate::patchHomographies(pair.gyro_homographies);
            }
            return AlignmentEstimate::patchHomographies(result.homographies);
          }};
}

struct WindowMeans {
  double capped = 0.0, uncapped = 0.0;
  std::size_t pairs = 0;
};

// Per method, per window of `window_s` of replay time, the capped and uncapped means. Each
// recording is on its own time unless `continued`: then the first `camera_recordings` follow one
// another (with `gap_s` between them, as replayed) and the twins that come after them take the time
// of their OIS recording (twin k of recording k).
std::map<std::string, std::vector<WindowMeans>> windowMeans(const deep_ois::EvaluationReport& report,
                                                            double window_s, bool continued,
                                                            std::size_t camera_recordings, double gap_s) {
  std::map<std::size_t, std::int64_t> first_stamp, last_stamp;  // per recording
  for (const auto& s : report.pairs) {
    auto it = first_stamp.find(s.recording);
    if (it == first_stamp.end() || s.stamp_a_ns < it->second) first_stamp[s.recording] = s.stamp_a_ns;
    auto jt = last_stamp.find(s.recording);
    if (jt == last_stamp.end() || s.stamp_b_ns > jt->second) last_stamp[s.recording] = s.stamp_b_ns;
  }
  std::map<std::size_t, double> offset_s;  // replay time of each camera recording's first stamp
  double replay_s = 0.0;
  for (std::size_t r = 0; r < camera_recordings; ++r) {
    offset_s[r] = replay_s;
    if (first_stamp.count(r)) replay_s += 1e-9 * static_cast<double>(last_stamp[r] - first_stamp[r]) + gap_s;
  }
  std::map<std::string, std::vector<WindowMeans>> out;
  for (const auto& s : report.pairs) {
    double t = 1e-9 * static_cast<double>(s.stamp_b_ns - first_stamp[s.recording]);
    if (continued) t += offset_s[s.recording < camera_recordings ? s.recording : s.recording - camera_recordings];
    const auto w = static_cast<std::size_t>(t / window_s);
    auto& windows = out[s.method];
    if (windows.size() <= w) windows.resize(w + 1);
    windows[w].capped += s.scored_px;
    windows[w].uncapped += std::isfinite(s.distance_px) ? s.distance_px : s.identity_px;
    ++windows[w].pairs;
  }
  for (auto& [method, windows] : out)
    for (auto& w : windows)
      if (w.pairs) {
        w.capped /= static_cast<double>(w.pairs);
        w.uncapped /= static_cast<double>(w.pairs);
      }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  deep_ois::ToolCommandLine command_line(
      "benchmark_online_learning",
      "Replays long recordings of one camera through the compensation's stabiliser path with its "
      "online learner, starting from a model with nothing learned, and prints the learning curve: "
      "per window of replay time, the paper's metric (capped and uncapped) of the learning "
      "compensation, the fixed starting model, the uncompensated OIS gyro and the non-OIS twin, and "
      "the share of the gap closed; with --no-ois, the compensation against the plain gyro.",
      "Exit status: 0 done, 1 nothing scored, 2 usage.");
  CLI::App& app = command_line.app();
  std::vector<std::string> bags, twins;
  const std::string package = ros::package::getPath("deep_ois");
  std::string model_path = package.empty() ? "" : package + "/models/stabiliser_generic.yaml";
  std::string gyro_config = package.empty() ? "" : package + "/config/gyro_flow.yaml";
  std::string plot_path, final_model_path;
  double window_s = 10.0, cpu_share = 0.3, gap_s = 1.0;
  bool no_ois = false, continue_bags = false, no_learning = false, online_calibration = false;
  bool no_rls = false, linear_rows = false;
  deep_ois::LinearDynamicsRlsOptions rls;
  double calibration_cpu_share = deep_ois::OnlineCalibrationOptions().cpu_share;
  app.add_option("--bags", bags, "the camera's recordings, replayed in this order (one long one is best)")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("FILE.bag ...");
  app.add_option("--twins", twins, "their non-OIS twins (simulator), for the gap closed")
      ->check(deep_ois::existingFile())
      ->type_name("FILE.bag ...");
  app.add_option("--model", model_path, "the starting stabiliser model")->capture_default_str()->check(deep_ois::existingFile());
  app.add_option("--gyro-config", gyro_config, "gyro flow parameters of the camera (YAML)")
      ->capture_default_str()
      ->check(deep_ois::existingFile());
  app.add_option("--plot", plot_path, "the learning curve as a PNG, its data beside it as FILE.csv")->type_name("FILE.png");
  app.add_option("--final-model", final_model_path, "writes the model in use at the end here")->type_name("FILE.yaml");
  command_line.addNumber("--window", window_s, "seconds of replay per row of the curve")->check(deep_ois::atLeast(1.0));
  command_line.addNumber("--cpu-share", cpu_share, "the learner's CPU budget, share of one core in replay time");
  app.add_flag("--no-ois", no_ois,
               "the recordings are of a camera without OIS (simulator bags made with --ois off, the "
               "non-OIS twin's pairs): scored against the plain gyro");
  app.add_flag("--no-learning", no_learning,
               "the learner checks every pair (residual, fallback to the plain gyro) but fits nothing: the "
               "live pipeline with ~learning false, e.g. for the output path's latency without the learning");
  app.add_flag("--no-rls", no_rls,
               "the learner without its recursive least squares on the linear-dynamics stage "
               "(~learning_rls false)");
  app.add_flag("--linear-rows", linear_rows,
               "the learner's fits also build the candidates with the linear-dynamics stage (off by "
               "default: OnlineLearningOptions::candidate_kinds.linear_dynamics)");
  command_line.addNumber("--rls-forgetting", rls.forgetting_per_s,
                         "the recursive least squares' forgetting factor per second (~learning_rls_forgetting)");
  command_line.addNumber("--rls-prior", rls.prior_lens_motions,
                         "what its starting coefficients are worth, in lens motions (~learning_rls_prior)");
  app.add_flag("--continue-bags", continue_bags,
               "the --bags are one camera's session, one after the other: the learner and its check go on "
               "(not restarted per recording), the stamps of each next recording are shifted to follow "
               "the previous one after --continue-gap, and the windows run on this continued time (twin k "
               "takes the time of recording k)");
  command_line.addNumber("--continue-gap", gap_s, "seconds between two recordings with --continue-bags (a gap: no learning window spans two recordings)")
      ->check(deep_ois::atLeast(0.1));
  app.add_flag("--online-calibration", online_calibration,
               "also run the compensation nodelet's online camera-IMU calibration (~online_calibration, the "
               "mount held) on the learner's tracks as it does live, the model's lens shifts removed, and "
               "print its CPU share, the learner's, their sum and its final state; it starts from "
               "--gyro-config's offset, readout, mount and bias and writes nothing");
  command_line.addNumber("--calibration-cpu-share", calibration_cpu_share,
                         "the online calibration's own budget, share of one core (~online_calibration_cpu_share)");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (!(calibration_cpu_share > 0.0 && calibration_cpu_share <= 1.0))
    return command_line.usageError("--calibration-cpu-share must be in (0, 1]");
  if (!(cpu_share > 0.0 && cpu_share <= 1.0)) return command_line.usageError("--cpu-share must be in (0, 1]");
  if (no_ois && !twins.empty()) return command_line.usageError("--no-ois takes no --twins (the bags are the twins)");
  if (continue_bags && !twins.empty() && twins.size() != bags.size())
    return command_line.usageError("--continue-bags needs one twin per recording (" + std::to_string(bags.size()) +
                                   " --bags, " + std::to_string(twins.size()) + " --twins)");

  deep_ois::StabiliserModelFile start;
  deep_ois::EvaluationOptions options;
  try {
    start = deep_ois::StabiliserModelFile::load(model_path);
    options.gyro = deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(gyro_config));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "benchmark_online_learning: %s\n", e.what());
    return 2;
  }
  options.bags = bags;
  options.bags.insert(options.bags.end(), twins.begin(), twins.end());
  options.ghost_pairs_per_category = 0;
  options.show_progress = false;

  deep_ois::OnlineLearningOptions learning;
  learning.cpu_share = cpu_share;
  learning.learning = !no_learning;
  learning.linear_dynamics_rls = !no_rls;
  learning.rls = rls;
  if (linear_rows) learning.candidate_kinds.linear_dynamics = true;
  if (const std::string problem = learning.validate(); !problem.empty())
    return command_line.usageError(problem);
  learning.max_queued_pairs = 100000;  // the replay keeps the queue at 10, as live
  auto path = std::make_shared<OnlinePath>();
  path->cpu_share = cpu_share;
  path->continue_bags = continue_bags;
  path->gap_s = gap_s;
  OnlinePath* const clock_owner = path.get();  // outlives the learner (reset first below)
  learning.budget_clock = [clock_owner] { return clock_owner->replay_clock_s.load(); };
  if (online_calibration) {
    path->calibration = std::make_shared<CalibrationRun>();
    CalibrationRun* const calibration = path->calibration.get();
    calibration->options.estimate_rotation = false;  // ~online_calibration_mount's default
    calibration->options.cpu_share = calibration_cpu_share;
    calibration->confirm_pairs = learning.confirmation.pairs;
    calibration->start_bias_rad_s = options.gyro.integration.gyro_bias_rad_s;
    calibration->lens_moves = !deep_ois::isNoLensMotion(start.parameters);
    learning.on_tracked_pair = [calibration](const deep_ois::OnlineFramePair& pair) { calibration->onTrackedPair(pair); };
  }
  path->learner = std::make_unique<deep_ois::OnlineStabiliserLearner>(
      learning, std::vector<deep_ois::ModelCandidate>{{"starting model", start.parameters}}, 0);

  const unsigned scope = no_ois ? deep_ois::kNonOisTwinPairs : deep_ois::kOisCameraPairs;
  deep_ois::EvaluationRunner runner(options);
  for (auto& method : deep_ois::gyroMethods()) runner.addMethod(method);
  runner.addMethod(deep_ois::stabiliserAlignmentMethod(kFixedMethod, start.parameters, scope));
  runner.addMethod(onlineMethod(path, scope));
  const auto started = std::chrono::steady_clock::now();
  const deep_ois::EvaluationReport report = runner.run();
  path->learner->waitIdle(120.0);
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  if (report.pairs.empty()) {
    std::fprintf(stderr, "benchmark_online_learning: nothing scored\n%s", report.markdown().c_str());
    return 1;
  }

  const auto means = windowMeans(report, window_s, continue_bags, bags.size(), gap_s);
  const std::string ois_gyro = deep_ois::kGyroOisMethod, twin_gyro = deep_ois::kGyroNonOisMethod;
  const std::string plain = no_ois ? twin_gyro : ois_gyro;
  auto at = [&](const std::string& method, std::size_t w) {
    auto it = means.find(method);
    return it != means.end() && w < it->second.size() && it->second[w].pairs ? it->second[w] : WindowMeans{};
  };
  std::size_t windows = 0;
  for (const auto& [method, rows] : means) windows = std::max(windows, rows.size());
  std::printf("Online learning from %s ('%s'), %.0f %% of a core, windows of %.0f s of replay\n",
              model_path.c_str(), start.name.c_str(), 100.0 * cpu_share, window_s);
  if (continue_bags && bags.size() > 1)
    std::printf("%zu recordings continued as one session, %.1f s between them (the learner's stamps shifted; "
                "the stabiliser's state starts again in each)\n",
                bags.size(), gap_s);
  std::printf("\n");
  std::vector<double> gap_online, gap_fixed, ratio_online, ratio_fixed;
  std::vector<double> window_end_s;  // the curve's x: the end of each window printed, s of replay
  if (!no_ois) {
    std::printf("| window [s] | pairs | OIS gyro | twin | fixed model | learning | gap closed: fixed | learning |\n");
    std::printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
  } else {
    std::printf("| window [s] | pairs | plain gyro | fixed model | learning | learning vs gyro |\n");
    std::printf("|---|---:|---:|---:|---:|---:|\n");
  }
  for (std::size_t w = 0; w < windows; ++w) {
    const WindowMeans g = at(plain, w), f = at(kFixedMethod, w), o = at(kOnlineMethod, w);
    // A last window of a few pairs (the recording's end) says nothing.
    if (o.pairs < static_cast<std::size_t>(5.0 * window_s)) continue;
    const std::string span = std::to_string(static_cast<int>(w * window_s)) + "-" +
                             std::to_string(static_cast<int>((w + 1) * window_s));
    window_end_s.push_back((w + 1) * window_s);
    if (!no_ois) {
      const WindowMeans t = at(twin_gyro, w);
      auto gap = [&](double g_px, double t_px, double m_px) {
        return t.pairs ? 100.0 * (g_px - m_px) / (g_px - t_px) : std::nan("");
      };
      gap_online.push_back(gap(g.capped, t.capped, o.capped));
      gap_fixed.push_back(gap(g.capped, t.capped, f.capped));
      std::printf("| %s | %zu | %.3f / %.3f | %.3f / %.3f | %.3f / %.3f | %.3f / %.3f | %.1f / %.1f %% | %.1f / %.1f %% |\n",
                  span.c_str(), o.pairs, g.capped, g.uncapped, t.capped, t.uncapped, f.capped, f.uncapped, o.capped,
                  o.uncapped, gap_fixed.back(), gap(g.uncapped, t.uncapped, f.uncapped), gap_online.back(),
                  gap(g.uncapped, t.uncapped, o.uncapped));
    } else {
      ratio_online.push_back(100.0 * (o.capped / g.capped - 1.0));
      ratio_fixed.push_back(100.0 * (f.capped / g.capped - 1.0));
      std::printf("| %s | %zu | %.3f / %.3f | %.3f / %.3f | %.3f / %.3f | %+.1f / %+.1f %% |\n", span.c_str(),
                  o.pairs, g.capped, g.uncapped, f.capped, f.uncapped, o.capped, o.uncapped, ratio_online.back(),
                  100.0 * (o.uncapped / g.uncapped - 1.0));
    }
  }
  const deep_ois::OnlineLearningStatus s = path->learner->status();
  std::printf("\n(cells: capped / uncapped Avg geometry distance, px)\n");
  for (const auto& [t, name] : path->swaps) std::printf("model swapped at %.1f s of replay: %s\n", t, name.c_str());
  const auto final_model = path->learner->model();
  std::printf("model at the end: %s (version %llu)%s\n", final_model->name.c_str(),
              static_cast<unsigned long long>(final_model->version),
              deep_ois::isNoLensMotion(final_model->parameters) ? " = no lens motion" : "");
  std::printf("last choice: %s\n", s.last_choice.c_str());
  if (!final_model_path.empty()) {
    try {
      deep_ois::StabiliserModelFile file;
      file.name = "benchmark_online_learning: " + final_model->name;
      file.parameters = final_model->parameters;
      file.training.target = "gyro-anchored lens shift (images), learned online";
      file.training.held_out_rms_px = final_model->held_out_rms_px;
      file.training.held_out_rms_without_model_px = final_model->held_out_rms_without_px;
      file.save(final_model_path);
      std::printf("model at the end written to %s\n", final_model_path.c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "benchmark_online_learning: %s\n", e.what());
    }
  }
  std::printf("learner: %zu pairs, %zu windows kept, %zu still, %zu failed, %zu fits (%zu failed), %zu swaps (%zu undone, "
              "%zu confirmed by the per-pair check, %zu undone by it); %zu windows replayed (not new evidence); "
              "%zu pairs not learned from (over the budget), %zu fits waited for their budget; fell back to the plain gyro on %zu of %zu pairs; CPU %.1f s over %.1f s of replay "
              "(%.0f %% of a core); wall %.1f s%s%s\n",
              s.pairs_submitted, s.windows_kept, s.windows_still, s.windows_failed, s.fits, s.fits_failed, s.swaps, s.swaps_undone,
              s.swaps_confirmed, s.swaps_undone_by_pairs, s.windows_repeated,
              s.pairs_over_budget, s.fits_delayed_by_budget, path->fallback_pairs, path->pairs, s.cpu_s, path->replay_s + path->last_stamp_s - path->recording_start_s,
              100.0 * s.cpu_s / std::max(1e-9, path->replay_s + path->last_stamp_s - path->recording_start_s), wall_s,
              s.last_problem.empty() ? "" : "; last problem: ", s.last_problem.c_str());
  {
    const double replay_s = std::max(1e-9, path->replay_s + path->last_stamp_s - path->recording_start_s);
    std::printf("linear stage: recursive least squares %s (forgetting %.3f per s, prior %.0f lens motions): %zu windows, "
                "%zu lens motions fed, CPU %.2f s (%.1f %% of a core, %.1f us per lens motion), %zu swaps to its model; "
                "linear-dynamics rows %s: CPU %.2f s (%.1f %% of a core)\n",
                no_rls ? "off" : "on", rls.forgetting_per_s, rls.prior_lens_motions, s.rls_windows, s.rls_lens_motions,
                s.rls_cpu_s, 100.0 * s.rls_cpu_s / replay_s,
                s.rls_lens_motions ? 1e6 * s.rls_cpu_s / static_cast<double>(s.rls_lens_motions) : 0.0, s.rls_swaps,
                linear_rows ? "on" : "off", s.linear_rows_cpu_s, 100.0 * s.linear_rows_cpu_s / replay_s);
  }
  std::printf("output path per pair (the compensator's step, the lens kept for the online calibration when on, the hand-over "
              "to the learner, the fallback read; "
              "not the benchmark's frame copy or its wait for the learner's queue): p50 %.3f ms, p95 %.3f ms, "
              "max %.3f ms over %zu pairs, learning %s, online calibration %s\n",
              percentile(path->output_ms, 0.5), percentile(path->output_ms, 0.95),
              path->output_ms.empty() ? std::nan("") : *std::max_element(path->output_ms.begin(), path->output_ms.end()),
              path->output_ms.size(), no_learning ? "off (checks only)" : "on", online_calibration ? "on" : "off");
  if (path->calibration) {
    const CalibrationRun& c = *path->calibration;
    const double replay_s = std::max(1e-9, path->replay_s + path->last_stamp_s - path->recording_start_s);
    // The learner's CPU includes its on_tracked_pair hook (the calibration is charged to its budget, as live).
    std::printf("CPU over %.1f s of replay (share of one core): online calibration %.1f %% (%.1f s, its hook on %zu "
                "tracked pairs), learner without it %.1f %% (%.1f s), together %.1f %% (%.1f s)\n",
                replay_s, 100.0 * c.cpu_s / replay_s, c.cpu_s, c.pairs, 100.0 * (s.cpu_s - c.cpu_s) / replay_s,
                s.cpu_s - c.cpu_s, 100.0 * s.cpu_s / replay_s, s.cpu_s);
    if (c.session) {
      const deep_ois::OnlineCalibrationStatus& st = c.session->status();
      const deep_ois::CameraImuCalibration& a = c.session->inUse();
      const deep_ois::CameraImuCalibration& e = st.estimate;
      std::printf("online calibration at the end: %s; applied (version %u): time offset %.3f ms, readout %.3f ms, "
                  "gyro bias (%.5f, %.5f, %.5f) rad/s; estimate: time offset %.3f +- %.3f ms, readout %.3f +- %.3f "
                  "ms, gyro bias (%.5f, %.5f, %.5f) +- (%.5f, %.5f, %.5f) rad/s\n",
                  st.state.c_str(), c.session->appliedVersion(), 1e3 * a.time_offset_s, 1e3 * a.readout_time_s,
                  a.gyro_bias_rad_s(0), a.gyro_bias_rad_s(1), a.gyro_bias_rad_s(2), 1e3 * e.time_offset_s,
                  1e3 * e.time_offset_sigma_s, 1e3 * e.readout_time_s, 1e3 * e.readout_time_sigma_s,
                  e.gyro_bias_rad_s(0), e.gyro_bias_rad_s(1), e.gyro_bias_rad_s(2), e.gyro_bias_sigma_rad_s(0),
                  e.gyro_bias_sigma_rad_s(1), e.gyro_bias_sigma_rad_s(2));
      std::printf("online calibration counts: %zu pairs (%zu without tracks), %zu fits (%zu needing motion, %zu "
                  "rejected, %zu over budget), %zu jumps, %zu swaps applied (%zu undone, %zu confirmed); its own "
                  "estimator CPU %.1f s\n",
                  st.pairs, st.pairs_without_tracks, st.fits, st.fits_needing_motion, st.fits_rejected,
                  st.fits_over_budget, st.jumps, st.swaps, c.session->swapsUndone(), c.session->swapsConfirmed(),
                  st.cpu_s);
      if (!st.last_reason.empty()) std::printf("online calibration last: %s\n", st.last_reason.c_str());
      if (!c.last_log.empty()) std::printf("online calibration last change: %s\n", c.last_log.c_str());
    } else {
      std::printf("online calibration: no tracked pair reached it\n");
    }
    if (!c.problem.empty()) std::printf("online calibration: last problem: %s\n", c.problem.c_str());
  }
  if (!plot_path.empty()) {
    // The table's rows as CSV beside the PNG (PATH.png -> PATH.csv), then the curve from it.
    std::string csv_path = plot_path;
    if (csv_path.size() > 4 && csv_path.substr(csv_path.size() - 4) == ".png") csv_path.resize(csv_path.size() - 4);
    csv_path += ".csv";
    deep_ois::CsvPlot plot;
    plot.x_column = "window_end_s";
    plot.x_label = "replay time at the end of the window of " + std::to_string(static_cast<int>(window_s)) + " s [s]";
    plot.curves = {{"learning_pct", "learning online"}, {"fixed_pct", "fixed starting model"}};
    plot.reference_lines = {0.0};
    if (no_ois) {
      plot.title = "benchmark_online_learning (camera without OIS): compensation against the plain gyro";
      plot.y_labels = {"worse than the plain gyro [%], capped"};
    } else {
      plot.title = "benchmark_online_learning: gap to the non-OIS twin closed";
      plot.y_labels = {"gap closed to the non-OIS twin [%], capped"};
      plot.reference_lines.push_back(100.0);
    }
    try {
      deep_ois::writeCsvColumns(csv_path, {{"window_end_s", window_end_s},
                                           {"learning_pct", no_ois ? ratio_online : gap_online},
                                           {"fixed_pct", no_ois ? ratio_fixed : gap_fixed}});
      const deep_ois::PlotOutcome outcome = deep_ois::plotCsv(plot, csv_path, plot_path);
      std::printf("learning curve: %s\n", (outcome.written ? plot_path : csv_path).c_str());
      if (!outcome.written)
        std::fprintf(stderr, "benchmark_online_learning: %s\n", deep_ois::describePlot(outcome, csv_path, plot_path).c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "benchmark_online_learning: %s\n", e.what());
    }
  }
  path->learner.reset();  // its threads end before the clock they read
  return 0;
}
