// The boundary of every ROS callback of the live nodelets: nothing thrown inside gets out.
//
// Why: an exception that leaves a callback terminates the nodelet manager and every nodelet
// loaded in it. Whatever throws (torch on an input the model refuses, an OpenCV assertion,
// std::invalid_argument from a core class), the message is lost, not the process: the error is
// counted and said in a throttled warning naming the topic and the problem.
#pragma once

#include <ros/console.h>

#include <cstddef>
#include <exception>
#include <string>

namespace deep_ois {

constexpr double kCallbackErrorWarnPeriodS = 2.0;

// Runs `handle()`; on an exception logs "<instance>: error while handling a message on <topic>
// (<n> so far): <what>" (throttled, on the `logger` logger; the instance is the nodelet's name, so
// two cameras in one manager are told apart) and increments `errors`. Returns false when it threw.
template <typename Handle>
bool runGuarded(const char* logger, const std::string& instance, const std::string& topic,
                std::size_t& errors, Handle&& handle) {
  try {
    handle();
    return true;
  } catch (const std::exception& e) {
    ++errors;
    ROS_WARN_THROTTLE_NAMED(kCallbackErrorWarnPeriodS, logger,
                            "%s: error while handling a message on %s (%zu so far): %s",
                            instance.c_str(), topic.c_str(), errors, e.what());
  } catch (...) {
    ++errors;
    ROS_WARN_THROTTLE_NAMED(kCallbackErrorWarnPeriodS, logger,
                            "%s: error while handling a message on %s (%zu so far): unknown exception",
                            instance.c_str(), topic.c_str(), errors);
  }
  return false;
}

}  // namespace deep_ois
