// Nodelet shell of deep_ois::FundamentalMixturesOffline: runs the offline job once, in its own
// thread (a long job must not block the manager's onInit), and logs the summary. Unloading the
// nodelet sets the stop flag; the job closes the output bag after the current pair.
#include <nodelet/nodelet.h>

#include <atomic>
#include <memory>
#include <pluginlib/class_list_macros.hpp>
#include <string>
#include <thread>

#include "deep_ois/ros/fundamental_mixtures_offline.h"

namespace deep_ois {

class FundamentalMixturesNodelet : public nodelet::Nodelet {
 public:
  ~FundamentalMixturesNodelet() override {
    stop_ = true;
    if (worker_.joinable()) worker_.join();
  }

 private:
  void onInit() override {
    try {
      job_ = std::make_unique<FundamentalMixturesOffline>(
          loadFundamentalMixturesOfflineOptions(getPrivateNodeHandle()));
    } catch (const std::exception& e) {
      NODELET_FATAL("%s", e.what());
      throw;
    }
    worker_ = std::thread([this] {
      try {
        const FundamentalMixturesSummary summary = job_->run(&stop_);
        std::string text = summary.text();
        if (!text.empty() && text.back() == '\n') text.pop_back();
        NODELET_INFO("wrote %s: %s", job_->options().output_path.c_str(), text.c_str());
      } catch (const std::exception& e) {
        NODELET_ERROR("%s", e.what());
      }
    });
  }

  std::atomic<bool> stop_{false};
  std::unique_ptr<FundamentalMixturesOffline> job_;
  std::thread worker_;  // declared last: joined (in the destructor) before the job goes away
};

}  // namespace deep_ois

PLUGINLIB_EXPORT_CLASS(deep_ois::FundamentalMixturesNodelet, nodelet::Nodelet)
