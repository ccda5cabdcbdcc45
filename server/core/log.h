// rangex's log, through spdlog: one line per event on stderr, where systemd or a container
// runtime collects it, with the UTC time, the level, the event's name and what happened:
//   2026-11-26T07:40:01.123Z warning store_failed: the store failed: disk full; ...
// The event names are stable (a plant's log tooling may match them); the text is for people.
// Included by .cpp files only (spdlog and fmt are heavy).
#pragma once
#include <spdlog/spdlog.h>

#include <utility>

namespace rangex::log {

spdlog::logger& logger();

template <typename... Args>
void info(const char* event, fmt::format_string<Args...> text, Args&&... args) {
  logger().info("{}: {}", event, fmt::format(text, std::forward<Args>(args)...));
}
template <typename... Args>
void warn(const char* event, fmt::format_string<Args...> text, Args&&... args) {
  logger().warn("{}: {}", event, fmt::format(text, std::forward<Args>(args)...));
}
template <typename... Args>
void error(const char* event, fmt::format_string<Args...> text, Args&&... args) {
  logger().error("{}: {}", event, fmt::format(text, std::forward<Args>(args)...));
}

}  // namespace rangex::log
