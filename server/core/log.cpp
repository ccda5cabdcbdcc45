#include "core/log.h"

#include <spdlog/sinks/stdout_sinks.h>

namespace rangex::log {

spdlog::logger& logger() {
  static const std::shared_ptr<spdlog::logger> l = [] {
    auto sink = std::make_shared<spdlog::sinks::stderr_sink_mt>();
    auto made = std::make_shared<spdlog::logger>("rangex", sink);
    made->set_pattern("%Y-%m-%dT%H:%M:%S.%eZ %l %v", spdlog::pattern_time_type::utc);
    made->flush_on(spdlog::level::info);  // a line is out before a crash can lose it
    return made;
  }();
  return *l;
}

// Made while the program starts, before any thread: the first log lines of a server often
// come from two of its threads at once, and a copy instrumented by ThreadSanitizer does not
// see this (uninstrumented) unit's guard of `l`, so it reported the logger's construction
// as racing with the other thread's use.
const bool made_at_start = (logger(), true);

}  // namespace rangex::log
