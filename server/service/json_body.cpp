#include "service/json_body.h"

#include <nlohmann/json.hpp>

namespace rangex {

std::string json_body(const nlohmann::json& j) {
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace rangex
