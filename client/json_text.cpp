#include "json_text.h"

#include <nlohmann/json.hpp>

namespace rangex::cli {

std::string json_text(const std::string& s) {
  return nlohmann::json(s).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace rangex::cli
