#include <cstdlib>
#include <filesystem>

#include "commands.h"

namespace fs = std::filesystem;

namespace rangex::cli {

std::string config_path(const std::string& opt) {
  if (!opt.empty()) return opt;
  if (const char* env = std::getenv("RANGEX_CONFIG")) return env;
  if (fs::exists("config/plant.yaml")) return "config/plant.yaml";
  return RANGEX_DEFAULT_CONFIG;
}

PlantConfig load_config(const std::string& opt) {
  return load_plant_config(config_path(opt));
}

}  // namespace rangex::cli
