#include "core/json_text.h"

#include <nlohmann/json.hpp>

namespace rangex {

std::string json_text(const std::string& s) {
  return json_dump(nlohmann::json(s));
}

std::string json_dump(const nlohmann::json& j, int indent) {
  return j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace rangex
