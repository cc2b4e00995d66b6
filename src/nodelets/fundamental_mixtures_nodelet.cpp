// Nodelet shell of deep_ois::FundamentalMixturesOffline: runs the offline job once, in its own
// thread (a long job must not block the manager's onInit), logs the summary and publishes it,
// latched, on ~summary (std_msgs/String) so that scripts and tests can wait for the end. Unloading
// the nodelet (also when its manager shuts down on Ctrl-C) sets the stop flag; the job closes the
// output bag after the current pair.
#include <nodelet/nodelet.h>
#include <ros/publisher.h>
#include <std_msgs/String.h>

#include <atomic>
#include <memory>
#include <pluginlib/class_list_macros.hpp>
#include <string>
#include <thread>

#include "deep_ois/ros/bag/fundamental_mixtures_offline.h"

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
    summary_publisher_ = getPrivateNodeHandle().advertise<std_msgs::String>("summary", 1, true);
    worker_ = std::thread([this] {
      std_msgs::String summary_msg;
      try {
        const FundamentalMixturesSummary summary = job_->run(&stop_);
        std::string text = summary.text();
        if (!text.empty() && text.back() == '\n') text.pop_back();
        NODELET_INFO("wrote %s: %s", job_->options().output_path.c_str(), text.c_str());
        summary_msg.data = "wrote " + job_->options().output_path + ": " + text;
      } catch (const std::exception& e) {
        NODELET_ERROR("%s", e.what());
        summary_msg.data = std::string("failed: ") + e.what();
      }
      summary_publisher_.publish(summary_msg);
    });
  }

  std::atomic<bool> stop_{false};
  ros::Publisher summary_publisher_;
  std::unique_ptr<FundamentalMixturesOffline> job_;
  std::thread worker_;  // declared last: joined (in the destructor) before the job goes away
};

}  // namespace deep_ois

PLUGINLIB_EXPORT_CLASS(deep_ois::FundamentalMixturesNodelet, nodelet::Nodelet)
