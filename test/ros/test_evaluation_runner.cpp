// The evaluator (EvaluationRunner) on the committed sample bag and on tiny simulator bags written
// here: every row scored with the one metric, the twins' gyro row, a broken bag that costs only
// itself, pluggable methods (grid flows, failures), and user annotation files for a recording
// without simulator truth. No roscore needed.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <iostream>
#include <limits>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "deep_ois/core/evaluation/fused_table_row.h"
#include "deep_ois/core/evaluation/geometry_distance.h"
#include "deep_ois/core/evaluation/stabiliser_table_row.h"
#include "deep_ois/core/ois/stabiliser_model_file.h"
#include "deep_ois/core/evaluation/standard_table_rows.h"
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include "deep_ois/ros/bag/bag_sequence.h"
#include "deep_ois/ros/bag/calibration_bag_reader.h"
#include "deep_ois/ros/bag/fundamental_mixtures_offline.h"
#include "deep_ois/ros/messages/conversions.h"
#include "deep_ois/tools/support/evaluation_runner.h"
#include "deep_ois/tools/support/simulation_bag_writer.h"
#include "deep_ois/tools/support/stabiliser_oracle_row.h"

namespace deep_ois {
namespace {

std::string sourcePath(const std::string& relative) {
  return std::string(DEEP_OIS_SOURCE_DIR) + "/" + relative;
}

EvaluationOptions optionsFor(const std::vector<std::string>& bags) {
  EvaluationOptions options;
  options.bags = bags;
  options.gyro = loadGyroFlowParameters(YamlParameters(sourcePath("config/gyro_flow.yaml")));
  options.show_progress = false;
  return options;
}

StandardMethodOptions standardOptions(const EvaluationOptions& options, bool images) {
  StandardMethodOptions standard;
  standard.image_baselines = images;
  standard.ground_truth = images;
  standard.solver.patch_count = options.gyro.rolling_shutter.patch_count;
  return standard;
}

// A short bag of the sample configuration (256x192), OIS on or off, with its truth on
// `truth_topic` (a recording "without truth" hides it from the evaluator's default topic).
std::string writeBag(const std::string& name, bool ois, double duration_s,
                     const std::string& truth_topic = "/ground_truth/frame_pair") {
  const std::string path = ::testing::TempDir() + "/" + name + ".bag";
  sim::SimulatorConfig config =
      sim::loadSimulatorConfig(sourcePath("config/simulator/sample.yaml"));
  config.ois.enabled = ois;
  const sim::Simulator simulator(config, 3, duration_s);
  SimulationBagTopics topics;
  topics.frame_pair_truth = truth_topic;
  writeSimulationBag(simulator, path, rosbag::compression::Uncompressed, topics, nullptr);
  return path;
}

double identityMean(const std::vector<FramePairTruth>& truths, std::size_t count) {
  double sum = 0.0;
  for (std::size_t k = 0; k < count; ++k) {
    sum +=
        geometryDistance(unflattenPoints(truths[k].points_a), unflattenPoints(truths[k].points_b),
                         {Eigen::Matrix3d::Identity()}, static_cast<int>(truths[k].image_height));
  }
  return sum / static_cast<double>(count);
}

TEST(BagSequence, OnePassWithImagesGivesTheFrameReadersFramesAndTheSameSequence) {
  const std::string path = sourcePath("bags/sample.bag");
  std::vector<BagFrame> frames;
  const BagSequence with = readBagSequence(path, {}, BagReadFailure::kThrow, &frames), without = readBagSequence(path);
  BagFrameReader reader(path, "/camera/image_raw");
  BagFrame expected;
  std::size_t count = 0;
  while (reader.next(expected)) {
    ASSERT_LT(count, frames.size());
    EXPECT_EQ(frames[count].stamp, expected.stamp);
    EXPECT_EQ(cv::norm(frames[count].rgb, expected.rgb, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(frames[count].gray, expected.gray, cv::NORM_INF), 0.0);
    ++count;
  }
  EXPECT_EQ(count, frames.size());
  EXPECT_EQ(with.time_base, without.time_base);
  EXPECT_EQ(with.imu_samples.size(), without.imu_samples.size());
  EXPECT_EQ(with.frame_stamps, without.frame_stamps);
  EXPECT_EQ(with.truths.size(), without.truths.size());
  ASSERT_TRUE(with.imu_to_camera_rotation.has_value());
}

TEST(EvaluationRunner, ScoresEveryRowOnTheSampleBagWithPluggableMethods) {
  EvaluationOptions options = optionsFor({sourcePath("bags/sample.bag")});
  options.max_pairs_per_bag = 8;
  EvaluationRunner runner(options);
  runner.addMethods(standardAlignmentMethods(standardOptions(options, true)));
  // What the shipped model's row looks like: a function of the gyro flow grid (here the identity
  // map, so it must score like the gyro homographies it was rendered from).
  runner.addMethod({"gyro flow grid", kOisCameraPairs, [](const FramePairContext& pair) {
                      return AlignmentEstimate::gridFlow(pair.gyro_flow_grid.clone());
                    }});
  runner.addMethod({"throws", kBenchmarkPairs, [](const FramePairContext&) -> AlignmentEstimate {
                      throw std::runtime_error("boom");
                    }});
  EXPECT_THROW(
      runner.addMethod({"throws", kBenchmarkPairs,
                        [](const FramePairContext&) { return AlignmentEstimate::failed("x"); }}),
      std::invalid_argument);
  const EvaluationReport report = runner.run();
  ASSERT_TRUE(report.complete()) << report.markdown();
  const EvaluationTable& table = report.table;
  // The sample bag has OIS on: no non-OIS or unspecified gyro row; rows in registration order.
  const std::vector<std::string> expected_rows = {"identity",
                                                  "SIFT + RANSAC",
                                                  "SIFT + MAGSAC",
                                                  "ORB + RANSAC",
                                                  "ORB + MAGSAC",
                                                  "AKAZE + RANSAC",
                                                  "AKAZE + MAGSAC",
                                                  kGyroOisMethod,
                                                  kGlobalFundamentalMethod,
                                                  kFundamentalMixturesMethod,
                                                  "gyro flow grid",
                                                  "throws"};
  EXPECT_EQ(table.methods(), expected_rows);
  EXPECT_EQ(table.categories(), std::vector<std::string>{"RE"});
  for (const std::string& method : expected_rows)
    EXPECT_EQ(table.count(method, "RE"), 8u) << method;
  EXPECT_EQ(report.pairs.size(), 8u * expected_rows.size());
  EXPECT_EQ(report.recordings.at(0).pairs_scored, 8u);

  // Identity, computed here from the bag's truth.
  const BagSequence bag = readBagSequence(sourcePath("bags/sample.bag"));
  const double identity = identityMean(bag.truths, 8);
  EXPECT_NEAR(table.mean("identity", "RE"), identity, 1e-9);
  // Nothing is worse than identity after capping; the image baselines align a textured scene.
  for (const std::string& method : expected_rows)
    EXPECT_LE(table.mean(method, "RE"), identity + 1e-12) << method;
  EXPECT_LT(table.mean("SIFT + RANSAC", "RE"), 0.5 * identity);
  EXPECT_EQ(table.failures("SIFT + RANSAC", "RE"), 0u);
  // The grid flow (360x270 grid for a 256x192 camera, bilinear) scores like the homographies.
  EXPECT_NEAR(table.mean("gyro flow grid", "RE"), table.mean(kGyroOisMethod, "RE"), 0.01);
  // A throwing method is scored as identity, counted, with its reason.
  EXPECT_EQ(table.failures("throws", "RE"), 8u);
  EXPECT_NEAR(table.mean("throws", "RE"), identity, 1e-9);
  EXPECT_EQ(report.failure_reasons.at("throws").at("error: boom"), 8u);

  // One ghost sample (one recording, one category) with a panel per row.
  ASSERT_EQ(report.ghosts.size(), 1u);
  EXPECT_EQ(report.ghosts[0].panels.size(), expected_rows.size());
  EXPECT_EQ(report.ghosts[0].panels[0].ghost_rgb.size(), cv::Size(256, 192));

  const std::string out = ::testing::TempDir() + "/evaluation_out";
  std::filesystem::remove_all(out);
  const std::vector<std::string> written = writeEvaluationReport(report, out);
  for (const char* file : {"evaluation.csv", "evaluation.json", "evaluation_pairs.csv",
                           "bars_RE.png", "bars_Avg.png", "ghosts_RE.png"}) {
    EXPECT_TRUE(std::filesystem::is_regular_file(out + "/" + file)) << file;
    EXPECT_GT(std::filesystem::file_size(out + "/" + file), 100u) << file;
  }
  EXPECT_EQ(written.size(), 6u);
  // The bar charts are matplotlib's (scripts/plot_csv.py over evaluation.csv): 1000 px wide, a
  // row of 34 px per method.
  for (const char* file : {"bars_RE.png", "bars_Avg.png"}) {
    const cv::Mat bars = cv::imread(out + "/" + file);
    ASSERT_FALSE(bars.empty()) << file;
    EXPECT_EQ(bars.cols, 1000) << file;
    EXPECT_EQ(bars.rows, 110 + 34 * static_cast<int>(table.methods().size())) << file;
  }
  // evaluation.json holds the table's numbers, method by method.
  std::ifstream json_file(out + "/evaluation.json");
  const nlohmann::json json = nlohmann::json::parse(json_file);
  ASSERT_EQ(json.at("methods").size(), table.methods().size());
  for (std::size_t m = 0; m < table.methods().size(); ++m) {
    const std::string& method = table.methods()[m];
    const nlohmann::json& row = json.at("methods")[m];
    EXPECT_EQ(row.at("name"), method);
    EXPECT_NEAR(row.at("avg_px").get<double>(), table.average(method), 1e-9) << method;
    const nlohmann::json& re = row.at("categories").at("RE");
    EXPECT_EQ(re.at("pairs").get<std::size_t>(), table.count(method, "RE")) << method;
    EXPECT_NEAR(re.at("mean_px").get<double>(), table.mean(method, "RE"), 1e-9) << method;
    EXPECT_EQ(re.at("failed").get<std::size_t>(), table.failures(method, "RE")) << method;
  }
  EXPECT_EQ(json.at("recordings").at(0).at("pairs_scored").get<std::size_t>(),
            report.recordings.at(0).pairs_scored);
}

TEST(EvaluationRunner, TwinsScoreOnlyTheNonOisGyroRowAndABrokenBagCostsOnlyItself) {
  const std::string ois = writeBag("eval_ois", true, 0.2), twin = writeBag("eval_twin", false, 0.2);
  const std::string missing = ::testing::TempDir() + "/no_such.bag";
  EvaluationOptions options = optionsFor({ois, missing, twin});
  EvaluationRunner runner(options);
  runner.addMethods(standardAlignmentMethods(standardOptions(options, false)));
  const EvaluationReport report = runner.run();
  ASSERT_EQ(report.recordings.size(), 3u);
  EXPECT_EQ(report.recordings[0].error, "");
  EXPECT_EQ(report.recordings[1].error.rfind(missing + ": cannot open the bag", 0), 0u)
      << report.recordings[1].error;
  EXPECT_EQ(report.recordings[2].error, "");
  EXPECT_FALSE(report.complete());
  const EvaluationTable& table = report.table;
  const std::size_t pairs = report.recordings[0].pairs_scored;
  ASSERT_GE(pairs, 4u);
  EXPECT_EQ(report.recordings[2].pairs_scored, pairs);
  EXPECT_EQ(table.methods(),
            (std::vector<std::string>{"identity", kGyroNonOisMethod, kGyroOisMethod}));
  // Identity is the OIS camera's (the benchmark); the twin adds only its gyro row.
  EXPECT_EQ(table.count("identity", "RE"), pairs);
  EXPECT_EQ(table.count(kGyroOisMethod, "RE"), pairs);
  EXPECT_EQ(table.count(kGyroNonOisMethod, "RE"), pairs);
  EXPECT_NEAR(table.mean("identity", "RE"), identityMean(readBagSequence(ois).truths, pairs), 1e-9);
  // The OIS problem: the gyro misses on the OIS camera and not on its twin.
  EXPECT_LT(table.mean(kGyroNonOisMethod, "RE"), 0.5 * table.mean(kGyroOisMethod, "RE"));
  EXPECT_NE(report.markdown().find("**not scored**: " + missing), std::string::npos);

  // The camera of each readable recording, which evaluate compares with each model row's.
  const CameraDescription camera = report.recordings[0].camera;
  ASSERT_TRUE(camera.known());
  // The recordings' frame rate (sample.yaml: 30 fps) is known, so a model of a 60 fps camera is
  // not reported as trained for "the camera of every recording".
  EXPECT_NEAR(camera.frame_rate_hz, 30.0, 0.01);
  CameraDescription sixty_fps = camera;
  sixty_fps.frame_rate_hz = 60.0;
  EXPECT_NE(modelCameraNote("m.yaml", sixty_fps, report.recordings).find("frame rate differs"),
            std::string::npos);
  EXPECT_FALSE(report.recordings[1].camera.known());
  EXPECT_EQ(camera.readout_time_s, options.gyro.rolling_shutter.readout_time_s);
  EXPECT_EQ(camera.differencesTo(report.recordings[2].camera), "");
  EXPECT_EQ(modelCameraNote("m.pt", camera, report.recordings),
            "m.pt: trained for " + camera.summary() + ", the camera of every recording");
  CameraDescription larger = camera;
  larger.width *= 2;
  const std::string note = modelCameraNote("m.pt", larger, report.recordings);
  EXPECT_EQ(note.rfind("m.pt was trained for " + larger.summary() + " but 2 of 2 recordings are of another camera "
                       "(first: " + ois + ": " + camera.summary() + "; image size differs",
                       0),
            0u)
      << note;
  EXPECT_EQ(modelCameraNote("m.pt", CameraDescription{}, report.recordings), "m.pt records no camera (a generic model)");
}

// The "gyro + lens log" row: offered only when a bag holds the camera's lens log (the OIS bag, not
// its twin); every pair covered; on the OIS camera it does what the twin's gyro does, where the
// uncompensated gyro misses by pixels.
TEST(EvaluationRunner, LensLogRowOnTheOisCameraMatchesTheTwinsGyro) {
  const std::string ois = writeBag("eval_lens_ois", true, 0.5), twin = writeBag("eval_lens_twin", false, 0.5);
  EXPECT_TRUE(recordingsHaveLensShiftLog(optionsFor({twin, ois})));
  EXPECT_FALSE(recordingsHaveLensShiftLog(optionsFor({twin})));
  EvaluationOptions without_log = optionsFor({ois});
  without_log.gyro.use_lens_shift_log = false;
  EXPECT_FALSE(recordingsHaveLensShiftLog(without_log));

  EvaluationOptions options = optionsFor({ois, twin});
  EvaluationRunner runner(options);
  runner.addMethods(gyroMethods());
  runner.addMethod(gyroLensLogMethod());
  const EvaluationReport report = runner.run();
  const EvaluationTable& table = report.table;
  const std::size_t pairs = report.recordings[0].pairs_scored;
  ASSERT_GE(pairs, 10u);
  EXPECT_EQ(table.count(kGyroLensLogMethod, "RE"), pairs);
  EXPECT_EQ(report.failure_reasons.count(kGyroLensLogMethod), 0u) << "a pair the log did not cover";
  const double lens = table.mean(kGyroLensLogMethod, "RE"), twin_gyro = table.mean(kGyroNonOisMethod, "RE"),
               ois_gyro = table.mean(kGyroOisMethod, "RE");
  std::cout << "[ measured ] " << pairs << " pairs: gyro + lens log " << lens << " px, twin's gyro " << twin_gyro
            << " px, OIS gyro uncompensated " << ois_gyro << " px\n";
  EXPECT_LT(lens, 0.5 * ois_gyro);
  EXPECT_LT(lens, 1.2 * twin_gyro);
}

TEST(EvaluationRunner, StabiliserOracleRowRunsTheBagsDesignOnItsGyro) {
  const std::string ois = writeBag("eval_oracle_ois", true, 0.5),
                    twin = writeBag("eval_oracle_twin", false, 0.5);
  const sim::SimulatorConfig own = sim::loadSimulatorConfig(sourcePath("config/simulator/sample.yaml"));
  // Another camera's design (360x270): not this recording's, every pair refused, saying why.
  const sim::SimulatorConfig other = sim::loadSimulatorConfig(sourcePath("config/simulator/RE.yaml"));
  EvaluationRunner runner(optionsFor({ois, twin}));
  runner.addMethods(gyroMethods());
  const double at_first_gyro_sample = std::numeric_limits<double>::quiet_NaN();
  runner.addMethod(stabiliserOracleMethod("oracle, own", own, at_first_gyro_sample));
  runner.addMethod(stabiliserOracleMethod("oracle, other camera", other, at_first_gyro_sample));
  // Started with the simulator's stabiliser (0.25 s before the first frame, before the IMU).
  runner.addMethod(stabiliserOracleMethod("oracle, simulator's start", own, sim::kSimulatorMarginS));
  const EvaluationReport report = runner.run();
  const EvaluationTable& table = report.table;
  const std::size_t pairs = report.recordings[0].pairs_scored;
  ASSERT_GE(pairs, 10u);
  EXPECT_EQ(table.count("oracle, own", "RE"), pairs);
  EXPECT_EQ(report.failure_reasons.count("oracle, own"), 0u) << "a pair the gyro did not cover";
  const double oracle = table.mean("oracle, own", "RE"), twin_gyro = table.mean(kGyroNonOisMethod, "RE"),
               ois_gyro = table.mean(kGyroOisMethod, "RE");
  std::cout << "[ measured ] " << pairs << " pairs: oracle " << oracle << " px, twin's gyro "
            << twin_gyro << " px, OIS gyro uncompensated " << ois_gyro << " px\n";
  EXPECT_LT(oracle, 0.5 * ois_gyro);
  EXPECT_LT(oracle, 1.3 * twin_gyro);
  // Covered from its earlier start too; a different start, different figures.
  EXPECT_EQ(table.count("oracle, simulator's start", "RE"), pairs);
  EXPECT_EQ(report.failure_reasons.count("oracle, simulator's start"), 0u);
  EXPECT_NE(table.mean("oracle, simulator's start", "RE"), oracle);
  ASSERT_EQ(report.failure_reasons.count("oracle, other camera"), 1u);
  const auto& reasons = report.failure_reasons.at("oracle, other camera");
  ASSERT_EQ(reasons.size(), 1u);
  EXPECT_NE(reasons.begin()->first.find("256x192"), std::string::npos) << reasons.begin()->first;
  EXPECT_EQ(reasons.begin()->second, pairs);
}

// evaluate's fused row (the shipped stabiliser model refined by the pair's tracks) on a textured
// (RE) recording: present on every pair of the OIS camera, refining most of them, and no worse
// than its prior, the stabiliser row it refines.
TEST(EvaluationRunner, FusedRowOnATexturedRecordingIsNoWorseThanItsPrior) {
  const std::string ois = writeBag("eval_fused_ois", true, 1.0);
  const StabiliserModelFile model = StabiliserModelFile::load(sourcePath("models/stabiliser_generic.yaml"));
  EvaluationRunner runner(optionsFor({ois}));
  runner.addMethod(stabiliserAlignmentMethod("prior", model.parameters));
  auto tally = std::make_shared<FusionTally>();
  runner.addMethod(
      fusedAlignmentMethod("fused", stabiliserAlignmentMethod("prior of the fused row", model.parameters), {}, tally));
  // The gyro prior is for cameras without OIS: none here.
  runner.addMethod(fusedAlignmentMethod("fused gyro", gyroPriorMethod()));
  const EvaluationReport report = runner.run();
  const EvaluationTable& table = report.table;
  const std::size_t pairs = report.recordings[0].pairs_scored;
  ASSERT_GE(pairs, 20u);
  EXPECT_EQ(table.count("fused", "RE"), pairs);
  EXPECT_EQ(report.failure_reasons.count("fused"), 0u);
  EXPECT_EQ(table.count("fused gyro", "RE"), 0u);
  EXPECT_EQ(tally->pairs, pairs);
  EXPECT_GE(tally->refinedPairs(), pairs / 2) << tally->markdown();
  const double prior = table.mean("prior", "RE"), fused = table.mean("fused", "RE");
  std::cout << "[ measured ] " << pairs << " pairs: prior " << prior << " px, fused " << fused << " px; "
            << tally->summary() << "\n";
  EXPECT_LE(fused, prior);
  EXPECT_THROW(fusedAlignmentMethod("no prior", AlignmentMethod{"empty", kOisCameraPairs, nullptr}),
               std::invalid_argument);
}

// Writes an annotation file; returns its path.
std::string writeAnnotations(const std::string& name, const std::string& body) {
  const std::string path = ::testing::TempDir() + "/" + name + ".csv";
  std::ofstream(path)
      << "# written by test_evaluation_runner\nstamp_a,stamp_b,x_a,y_a,x_b,y_b,category\n"
      << body;
  return path;
}

TEST(EvaluationRunner, AnnotationFilesScoreARecordingWithoutTruth) {
  // The truth goes to a topic the evaluator does not read by default: a "real" recording.
  const std::string bag = writeBag("eval_real", true, 0.2, "/hidden/frame_pair");
  const BagSequence truth_view = [&] {
    BagSequenceTopics topics;
    topics.frame_pair_truth = "/hidden/frame_pair";
    return readBagSequence(bag, topics);
  }();
  ASSERT_GE(truth_view.truths.size(), 3u);

  // Without annotations there is nothing to score, and the message says what to do.
  {
    EvaluationRunner runner(optionsFor({bag}));
    runner.addMethods(gyroMethods());
    const EvaluationReport report = runner.run();
    EXPECT_NE(report.recordings[0].error.find("needs --annotations"), std::string::npos)
        << report.recordings[0].error;
  }

  // The annotation file holds the simulator's points of every pair.
  std::string body;
  for (const FramePairTruth& truth : truth_view.truths) {
    const auto a = unflattenPoints(truth.points_a), b = unflattenPoints(truth.points_b);
    for (std::size_t k = 0; k < a.size(); ++k) {
      body += formatStampNs(truth.previous_stamp.toNSec()) + "," +
              formatStampNs(truth.header.stamp.toNSec()) + "," + std::to_string(a[k].x()) + "," +
              std::to_string(a[k].y()) + "," + std::to_string(b[k].x()) + "," +
              std::to_string(b[k].y()) + ",real\n";
    }
  }
  // Scored with annotations (OIS state not given) and with the truth topic: the same numbers.
  EvaluationOptions annotated = optionsFor({bag});
  annotated.annotations = readAnnotationFile(writeAnnotations("eval_real_good", body));
  EvaluationRunner annotated_runner(annotated);
  annotated_runner.addMethods(standardAlignmentMethods(standardOptions(annotated, false)));
  const EvaluationReport report = annotated_runner.run();
  ASSERT_TRUE(report.complete()) << report.markdown();
  EXPECT_EQ(report.table.methods(), (std::vector<std::string>{"identity", kGyroMethod}));
  EXPECT_EQ(report.table.categories(), std::vector<std::string>{"real"});
  EXPECT_EQ(report.table.count(kGyroMethod, "real"), truth_view.truths.size());

  EvaluationOptions simulated = optionsFor({bag});
  simulated.topics.frame_pair_truth = "/hidden/frame_pair";
  EvaluationRunner simulated_runner(simulated);
  simulated_runner.addMethods(standardAlignmentMethods(standardOptions(simulated, false)));
  const EvaluationReport reference = simulated_runner.run();
  // std::to_string keeps 6 decimals: the points moved by < 1e-6 px.
  EXPECT_NEAR(report.table.mean("identity", "real"), reference.table.mean("identity", "RE"), 1e-5);
  EXPECT_NEAR(report.table.mean(kGyroMethod, "real"), reference.table.mean(kGyroOisMethod, "RE"),
              1e-5);

  // Said to be an OIS camera, the gyro row is the OIS camera's.
  annotated.annotated_scope = kOisCameraPairs;
  EvaluationRunner ois_runner(annotated);
  ois_runner.addMethods(gyroMethods());
  EXPECT_EQ(ois_runner.run().table.methods(), std::vector<std::string>{kGyroOisMethod});

  // Stamps that are not frames of the bag, and a point outside the image: errors naming file and
  // line; the good pairs are still scored.
  const std::string a0 = formatStampNs(truth_view.truths[0].previous_stamp.toNSec());
  const std::string b0 = formatStampNs(truth_view.truths[0].header.stamp.toNSec());
  const std::string b1 = formatStampNs(truth_view.truths[1].header.stamp.toNSec());
  const std::string b0_plus_1ns = formatStampNs(truth_view.truths[0].header.stamp.toNSec() + 1);
  const std::string bad_path = writeAnnotations(
      "eval_real_bad", a0 + "," + b0 + ",10,10,11,11,real\n" +               // line 3
                           a0 + ",1.5,10,10,11,11,real\n" +                  // line 4 (b earlier)
                           a0 + "," + b0_plus_1ns + ",10,10,11,11,real\n" +  // line 5
                           "1.0,2.0,10,10,11,11,real\n" +                    // line 6
                           b0 + "," + b1 + ",10,10,900,11,real\n");          // line 7
  EXPECT_THROW(readAnnotationFile(bad_path), std::runtime_error);  // line 4: stamp_b before stamp_a
  const std::string fixed_path = writeAnnotations(
      "eval_real_fixed", a0 + "," + b0 + ",10,10,11,11,real\n" +               // line 3: good
                             a0 + "," + b0_plus_1ns + ",10,10,11,11,real\n" +  // line 4: 1 ns off
                             "1.0,2.0,10,10,11,11,real\n" +            // line 5: no frame at all
                             b0 + "," + b1 + ",10,10,900,11,real\n");  // line 6: outside the image
  EvaluationOptions broken = optionsFor({bag});
  broken.annotations = readAnnotationFile(fixed_path);
  EvaluationRunner broken_runner(broken);
  broken_runner.addMethods(gyroMethods());
  const EvaluationReport partial = broken_runner.run();
  EXPECT_FALSE(partial.complete());
  EXPECT_EQ(partial.table.count(kGyroMethod, "real"), 1u);
  ASSERT_EQ(partial.errors.size(), 3u) << partial.markdown();
  EXPECT_EQ(partial.errors[0].rfind(
                fixed_path + ":4: stamp_b " + b0_plus_1ns + " is not a frame of " + bag, 0),
            0u)
      << partial.errors[0];
  EXPECT_EQ(partial.errors[1].rfind(
                fixed_path + ":6: point (900.000000, 11.000000) is outside the 256x192 image", 0),
            0u)
      << partial.errors[1];
  EXPECT_EQ(partial.errors[2],
            fixed_path + ":5: pair 1.000000000 -> 2.000000000 matches no frame of the bags given");
}

}  // namespace
}  // namespace deep_ois

namespace deep_ois {
namespace {

// A copy of bags/sample.bag without its IMU messages (its /tf_static transform stays).
std::string writeSampleWithoutImu() {
  const std::string path = ::testing::TempDir() + "/sample_without_imu.bag";
  rosbag::Bag in(std::string(DEEP_OIS_SOURCE_DIR) + "/bags/sample.bag", rosbag::bagmode::Read);
  rosbag::Bag out(path, rosbag::bagmode::Write);
  for (const rosbag::MessageInstance& m : rosbag::View(in)) {
    if (m.getTopic() != "/imu/data") out.write(m.getTopic(), m.getTime(), m, m.getConnectionHeader());
  }
  return path;
}

// Without IMU messages the tools say so, naming the topic, rather than blaming the transform
// (which is in /tf_static): evaluate, the Fundamental Mixtures job and calibrate's reader.
TEST(MissingImu, EveryOfflineToolNamesTheTopicNotTheTransform) {
  const std::string bag = writeSampleWithoutImu();
  const std::string expected = bag + ": no IMU messages on /imu/data (sensor_msgs/Imu topics in the bag: none)";

  const BagSequence sequence = readBagSequence(bag);
  EXPECT_TRUE(sequence.imu_samples.empty());
  EXPECT_EQ(bag + ": " + sequence.imu_problem, expected);
  EXPECT_EQ(sequence.imu_to_camera_problem.rfind(sequence.imu_problem, 0), 0u) << sequence.imu_to_camera_problem;

  EvaluationRunner runner(optionsFor({bag}));
  runner.addMethods(gyroMethods());
  const EvaluationReport report = runner.run();
  ASSERT_EQ(report.recordings.size(), 1u) << report.markdown();
  EXPECT_EQ(report.recordings[0].error.rfind(expected, 0), 0u) << report.recordings[0].error;

  FundamentalMixturesOfflineOptions fm;
  fm.bags = {bag};
  fm.output_path = ::testing::TempDir() + "/sample_without_imu_train.bag";
  fm.gyro = loadGyroFlowParameters(YamlParameters(std::string(DEEP_OIS_SOURCE_DIR) + "/config/gyro_flow.yaml"));
  const FundamentalMixturesSummary summary = FundamentalMixturesOffline(fm).run();
  ASSERT_EQ(summary.bag_errors.size(), 1u) << summary.text();
  EXPECT_EQ(summary.bag_errors[0].rfind(expected, 0), 0u) << summary.bag_errors[0];

  try {
    readCalibrationBag(bag, CalibrationBagOptions());
    ADD_FAILURE() << "calibrate's reader accepted a bag without IMU messages";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(expected, 0), 0u) << e.what();
  }

  // The transform is reported missing for what it is when the IMU is there but the tf is not.
  const BagSequence intact = readBagSequence(std::string(DEEP_OIS_SOURCE_DIR) + "/bags/sample.bag");
  EXPECT_TRUE(intact.imu_problem.empty());
  EXPECT_TRUE(intact.imu_to_camera_problem.empty());
  EXPECT_TRUE(intact.imu_to_camera_rotation.has_value());
}

}  // namespace
}  // namespace deep_ois
