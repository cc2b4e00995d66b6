// Writes a stabiliser model's predicted lens for a recording (rosbag): the lens position on a
// 5 ms grid, and per frame pair and row patch the predicted lens motion beside the recording's own
// (the simulator's truth, the camera's lens log or the gyro-anchored estimate from the images),
// as CSV and a PNG plot, with the R^2 and RMS of the motion.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "deep_ois/core/ois/stabiliser_fit.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/ros/bag/stabiliser_training_data.h"
#include "deep_ois/ros/live/gyro_flow_parameters.h"
#include "deep_ois/ros/live/parameter_source.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/csv_plot.h"

int main(int argc, char** argv) {
  deep_ois::ToolCommandLine command_line(
      "predict_lens",
      "Writes a stabiliser model's predicted lens for a recording: PREFIX_position.csv (the "
      "predicted lens shift every 5 ms), PREFIX_motion.csv and PREFIX_motion.png (per frame pair "
      "and row patch the predicted lens motion beside the recording's: simulator truth, lens log "
      "or the images' gyro-anchored estimate, by default the first the bag has), and prints the "
      "motion's R^2 and RMS error.",
      "Exit status: 0 written, 1 failed, 2 usage.");
  CLI::App& app = command_line.app();
  std::string bag, model_path, gyro_config, prefix, target = "auto";
  double warm_up_s = 1.0;
  app.add_option("--bag", bag, "the recording")->required()->check(deep_ois::existingFile());
  app.add_option("--model", model_path, "stabiliser model (YAML)")->required()->check(deep_ois::existingFile());
  app.add_option("--gyro-config", gyro_config, "gyro flow parameters of the camera (YAML)")
      ->required()->check(deep_ois::existingFile());
  app.add_option("--out", prefix, "output prefix")->required()->type_name("PREFIX");
  app.add_option("--target", target,
                 "the lens motion to compare with: truth (a simulated recording's), log (the "
                 "camera's lens-shift log), images (the gyro-anchored estimate) or auto (the first "
                 "of these three the bag has)")
      ->check(deep_ois::oneOf({"auto", "truth", "log", "images"}))->capture_default_str();
  command_line.addNumber("--warm-up", warm_up_s, "seconds of gyro before the first compared pair")
      ->check(deep_ois::atLeast(0));
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;

  try {
    const deep_ois::StabiliserModelFile model = deep_ois::StabiliserModelFile::load(model_path);
    const deep_ois::GyroFlowParameters gyro =
        deep_ois::loadGyroFlowParameters(deep_ois::YamlParameters(gyro_config));
    if (target == "auto") {
      target = deep_ois::lensMotionTargetName(deep_ois::lensMotionTargetOf(bag));
      std::fprintf(stderr, "predict_lens: comparing with the bag's %s (--target %s)\n",
                   target == "truth" ? "simulator truth" : target == "log" ? "lens-shift log" : "images",
                   target.c_str());
    }
    const deep_ois::StabiliserRecordingData data =
        deep_ois::readStabiliserRecording(bag, gyro, deep_ois::lensMotionTargetNamed(target));
    const deep_ois::StabiliserFitRecording& recording = data.recording;
    if (model.camera.width > 0) {
      const std::string difference = model.camera.differencesTo(data.camera);
      if (!difference.empty())
        std::fprintf(stderr, "predict_lens: WARNING: the model is for %s, the recording is %s (%s)\n",
                     model.camera.summary().c_str(), data.camera.summary().c_str(), difference.c_str());
    }
    if (recording.rates.empty()) throw std::runtime_error(bag + ": no gyro samples");
    // The position every 5 ms (the same predictor the nodelet runs).
    {
      deep_ois::LensShiftPredictor predictor(model.parameters, recording.focal_px);
      std::ofstream csv(prefix + "_position.csv");
      csv << "t_s,x_px,y_px\n";
      std::size_t next = 0;
      const double t0 = recording.rates.front().stamp_s;
      for (double t = t0; t <= recording.rates.back().stamp_s; t += 0.005) {
        while (next < recording.rates.size() && (!predictor.started() || predictor.newestStamp() < t))
          predictor.addRate(recording.rates[next++]);
        if (!predictor.covers(t)) continue;
        const Eigen::Vector2d s = predictor.lensShiftAt(t);
        csv << t - t0 << "," << s.x() << "," << s.y() << "\n";
      }
    }
    const auto predicted = deep_ois::predictLensMotion(model.parameters, recording, 1e-3, warm_up_s);
    std::vector<std::size_t> order;
    for (std::size_t k = 0; k < predicted.size(); ++k)
      if (predicted[k].allFinite()) order.push_back(k);
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return recording.observations[a].t_a_s < recording.observations[b].t_a_s;
    });
    std::ofstream csv(prefix + "_motion.csv");
    csv << "t_a_s,t_b_s,recorded_x_px,recorded_y_px,predicted_x_px,predicted_y_px\n";
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (std::size_t k : order) mean += recording.observations[k].motion_px;
    if (order.empty()) throw std::runtime_error(bag + ": no frame pair after the warm-up to compare");
    mean /= static_cast<double>(order.size());
    double error = 0.0, spread = 0.0;
    const double t0 = recording.rates.front().stamp_s;
    for (std::size_t k : order) {
      const auto& o = recording.observations[k];
      csv << o.t_a_s - t0 << "," << o.t_b_s - t0 << "," << o.motion_px.x() << "," << o.motion_px.y()
          << "," << predicted[k].x() << "," << predicted[k].y() << "\n";
      error += (predicted[k] - o.motion_px).squaredNorm();
      spread += (o.motion_px - mean).squaredNorm();
    }
    csv.close();
    if (!csv) throw std::runtime_error(prefix + "_motion.csv: cannot write");
    deep_ois::CsvPlot plot;
    plot.title = "predict_lens: lens motion per frame pair and row patch, " + target + " and predicted";
    plot.x_column = "t_a_s";
    plot.x_label = "start of the frame pair, time since the first gyro sample [s]";
    plot.y_labels = {"lens motion x [px]", "lens motion y [px]"};
    plot.curves = {{"recorded_x_px", target + " x", deep_ois::PlotRole::kLogged, 1},
                   {"predicted_x_px", "predicted x", deep_ois::PlotRole::kPredicted, 1},
                   {"recorded_y_px", target + " y", deep_ois::PlotRole::kLogged, 2},
                   {"predicted_y_px", "predicted y", deep_ois::PlotRole::kPredicted, 2}};
    plot.width_px = 1200;
    plot.height_px = 600;
    const deep_ois::PlotOutcome outcome = deep_ois::plotCsv(plot, prefix + "_motion.csv", prefix + "_motion.png");
    std::printf("%s: %zu lens motions compared (%zu before the warm-up or outside the gyro): R^2 "
                "%.4f, RMS error %.4f px; wrote %s_position.csv, %s_motion.csv; %s\n",
                bag.c_str(), order.size(), predicted.size() - order.size(), 1.0 - error / spread,
                std::sqrt(error / static_cast<double>(order.size())), prefix.c_str(), prefix.c_str(),
                deep_ois::describePlot(outcome, prefix + "_motion.csv", prefix + "_motion.png").c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "predict_lens: %s\n", e.what());
    return 1;
  }
  return 0;
}
