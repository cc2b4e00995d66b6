// Makes an annotation file (point correspondences per frame pair, the evaluator's CSV format) for
// a real recording, by a reproducible procedure: a plan file names, per pair of consecutive bag
// frames, the region a person chose (distant background) and, once the crops were inspected, the
// candidate ids that person accepted. The candidates themselves are deterministic
// (proposeCorrespondences: Shi-Tomasi corners + cornerSubPix, KLT with a forward-backward check,
// zoomed template matching that must agree with KLT, ZNCC), so the same bag and plan give the same
// file. Flags: --help.
//
// Plan lines ('#' starts a comment):
//   pair <bag frame index of a (0-based; b = a + 1)> region <x0> <y0> <x1> <y1> [accept <id> ...]
// --crops writes, per pair, pair_<a>_overview.png (frame a, region, numbered candidates) and
// pair_<a>_candidate_<id>.png (zoomed neighbourhoods in a | b with a cross on each point).
// --out writes the accepted candidates; every plan line must then have an accept list.
#include <ros/time.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "deep_ois/ros/bag/bag_frame_reader.h"
#include "deep_ois/tools/support/command_line.h"
#include "deep_ois/tools/support/correspondence_proposer.h"

namespace {

struct PlannedPair {
  int line = 0;
  int frame_a = 0;
  cv::Rect region;
  bool has_accept = false;
  std::vector<int> accepted;
};

std::vector<PlannedPair> readPlan(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open the plan");
  std::vector<PlannedPair> plan;
  std::set<int> seen;
  std::string text;
  int line = 0;
  while (std::getline(in, text)) {
    ++line;
    const std::string content = text.substr(0, text.find('#'));
    std::istringstream fields(content);
    std::string word;
    if (!(fields >> word)) continue;
    auto fail = [&](const std::string& problem) {
      throw std::runtime_error(path + ":" + std::to_string(line) + ": " + problem);
    };
    PlannedPair pair;
    pair.line = line;
    int x0, y0, x1, y1;
    std::string region_word;
    if (word != "pair" || !(fields >> pair.frame_a) || !(fields >> region_word) ||
        region_word != "region" || !(fields >> x0 >> y0 >> x1 >> y1)) {
      fail("expected 'pair <frame index> region <x0> <y0> <x1> <y1> [accept <id> ...]'");
    }
    if (pair.frame_a < 0) fail("the frame index must be >= 0");
    if (x1 <= x0 || y1 <= y0) fail("the region needs x0 < x1 and y0 < y1");
    if (!seen.insert(pair.frame_a).second)
      fail("pair " + std::to_string(pair.frame_a) + " is planned twice");
    pair.region = cv::Rect(cv::Point(x0, y0), cv::Point(x1, y1));
    if (fields >> word) {
      if (word != "accept") fail("expected 'accept' after the region, got '" + word + "'");
      pair.has_accept = true;
      int id;
      while (fields >> id) pair.accepted.push_back(id);
      if (!fields.eof()) fail("accept takes candidate ids (whole numbers)");
      if (pair.accepted.empty()) fail("accept needs at least one candidate id");
    }
    plan.push_back(pair);
  }
  if (plan.empty()) throw std::runtime_error(path + ": no 'pair' line");
  return plan;
}

std::string stampText(const ros::Time& stamp) {
  char text[32];
  std::snprintf(text, sizeof(text), "%u.%09u", stamp.sec, stamp.nsec);
  return text;
}

void writePng(const std::string& path, const cv::Mat& rgb) {
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  if (!cv::imwrite(path, bgr)) throw std::runtime_error(path + ": cannot write the image");
}

}  // namespace

constexpr char kDescription[] =
    "Makes an annotation file (point correspondences per frame pair, the evaluator's CSV format) "
    "for "
    "a real recording, by a reproducible procedure: a plan file names, per pair of consecutive bag "
    "frames, the region a person chose (distant background) and, once the crops were inspected, "
    "the "
    "candidate ids that person accepted. The candidates are deterministic (Shi-Tomasi corners, KLT "
    "with a forward-backward check, zoomed template matching, ZNCC), so the same bag and plan give "
    "the same file.";
constexpr char kFooter[] =
    "Plan lines ('#' starts a comment):\n"
    "  pair <frame index of a, 0-based; b = a + 1> region <x0> <y0> <x1> <y1> [accept <id> ...]\n"
    "--crops writes, per pair, pair_<a>_overview.png (frame a, region, numbered candidates) and\n"
    "pair_<a>_candidate_<id>.png (zoomed neighbourhoods in a | b with a cross on each point).\n"
    "--out writes the accepted candidates; every plan line must then have an accept list.\n"
    "Exit status: 0 written, 1 failed, 2 usage.";

int main(int argc, char** argv) {
  std::string bag, plan_path, crops_dir, out_path, image_topic = "/camera/image_raw",
                                                   category = "real";
  deep_ois::ToolCommandLine command_line("annotate_pairs", kDescription, kFooter);
  CLI::App& app = command_line.app();
  app.add_option("--bag", bag, "the recording")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("FILE.bag");
  app.add_option("--plan", plan_path, "the plan (format below)")
      ->required()
      ->check(deep_ois::existingFile())
      ->type_name("PLAN.txt");
  app.add_option("--crops", crops_dir, "write the crops to inspect into this folder")
      ->type_name("DIR");
  app.add_option("--out", out_path, "write the accepted candidates as an annotation file")
      ->type_name("FILE.csv");
  app.add_option("--image-topic", image_topic, "image topic of the bag")
      ->capture_default_str()
      ->type_name("TOPIC");
  app.add_option("--category", category, "category column of the annotation file (no commas)")
      ->capture_default_str()
      ->type_name("TEXT");
  if (const std::optional<int> status = command_line.parse(argc, argv)) return *status;
  if (crops_dir.empty() && out_path.empty()) {
    return command_line.usageError("nothing to do: give --crops DIR and/or --out FILE.csv");
  }
  if (category.empty() || category.find(',') != std::string::npos) {
    return command_line.usageError("--category must be non-empty without commas");
  }

  try {
    const std::vector<PlannedPair> plan = readPlan(plan_path);
    std::set<int> needed;
    for (const PlannedPair& pair : plan) {
      needed.insert(pair.frame_a);
      needed.insert(pair.frame_a + 1);
    }
    std::map<int, deep_ois::BagFrame> frames;
    deep_ois::BagFrameReader reader(bag, image_topic);
    deep_ois::BagFrame frame;
    for (int index = 0; index <= *needed.rbegin() && reader.next(frame); ++index) {
      if (!needed.count(index)) continue;
      // The reader may decode the next frame into the same buffers: keep deep copies.
      deep_ois::BagFrame& kept = frames[index];
      kept.stamp = frame.stamp;
      kept.frame_id = frame.frame_id;
      kept.rgb = frame.rgb.clone();
      kept.gray = frame.gray.clone();
    }

    const deep_ois::CorrespondenceProposerOptions options;
    std::ostringstream csv;
    std::size_t points = 0;
    for (const PlannedPair& pair : plan) {
      if (!frames.count(pair.frame_a) || !frames.count(pair.frame_a + 1)) {
        throw std::runtime_error(plan_path + ":" + std::to_string(pair.line) + ": frames " +
                                 std::to_string(pair.frame_a) + " and " +
                                 std::to_string(pair.frame_a + 1) + " are not both in " + bag +
                                 " (" + std::to_string(reader.frameCount()) + " frames on " +
                                 image_topic + ")");
      }
      const deep_ois::BagFrame& a = frames[pair.frame_a];
      const deep_ois::BagFrame& b = frames[pair.frame_a + 1];
      const auto candidates =
          deep_ois::proposeCorrespondences(a.gray, b.gray, pair.region, options);
      std::printf("pair %d -> %d (stamps %s -> %s): %zu candidates\n", pair.frame_a,
                  pair.frame_a + 1, stampText(a.stamp).c_str(), stampText(b.stamp).c_str(),
                  candidates.size());
      for (const auto& c : candidates) {
        std::printf(
            "  %2d  a (%8.3f, %8.3f)  b (%8.3f, %8.3f)  motion %6.3f px  fb %.3f px  "
            "klt-vs-template "
            "%.3f px  zncc %.4f\n",
            c.id, c.point_a_px.x, c.point_a_px.y, c.point_b_px.x, c.point_b_px.y,
            cv::norm(c.point_b_px - c.point_a_px), c.forward_backward_error_px, c.disagreement_px,
            c.zncc);
      }
      if (!crops_dir.empty()) {
        const std::string prefix = crops_dir + "/pair_" + std::to_string(pair.frame_a);
        writePng(prefix + "_overview.png",
                 deep_ois::renderCandidateOverview(a.rgb, pair.region, candidates));
        for (const auto& c : candidates) {
          writePng(prefix + "_candidate_" + std::to_string(c.id) + ".png",
                   deep_ois::renderCandidateCrop(a.rgb, b.rgb, c));
        }
      }
      if (out_path.empty()) continue;
      if (!pair.has_accept) {
        throw std::runtime_error(plan_path + ":" + std::to_string(pair.line) +
                                 ": no accept list (inspect the crops, then list the ids to keep)");
      }
      for (int id : pair.accepted) {
        if (id < 0 || id >= static_cast<int>(candidates.size())) {
          throw std::runtime_error(plan_path + ":" + std::to_string(pair.line) + ": candidate " +
                                   std::to_string(id) + " does not exist (the pair has " +
                                   std::to_string(candidates.size()) + ")");
        }
        const auto& c = candidates[id];
        char row[256];
        std::snprintf(row, sizeof(row), "%s,%s,%.3f,%.3f,%.3f,%.3f,%s\n",
                      stampText(a.stamp).c_str(), stampText(b.stamp).c_str(), c.point_a_px.x,
                      c.point_a_px.y, c.point_b_px.x, c.point_b_px.y, category.c_str());
        csv << row;
        ++points;
      }
    }
    if (!out_path.empty()) {
      std::ofstream out(out_path);
      out << "# Point correspondences for the evaluator (format: data/annotations/README.md).\n"
          << "# Written by: annotate_pairs --bag " << bag << " --plan " << plan_path << "\n"
          << "# Candidates proposed automatically, each accepted by a person on its zoomed crop.\n"
          << "stamp_a,stamp_b,x_a,y_a,x_b,y_b,category\n"
          << csv.str();
      if (!out) throw std::runtime_error(out_path + ": cannot write");
      std::printf("annotate_pairs: %s: %zu pairs, %zu points\n", out_path.c_str(), plan.size(),
                  points);
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "annotate_pairs: %s\n", e.what());
    return 1;
  }
}
