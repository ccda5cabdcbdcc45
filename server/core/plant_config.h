// Plant configuration (config/plant.yaml): lanes, sensors, geometry, thresholds, backend,
// storage and listen address. Loading validates every value and names the key at fault.
#pragma once
#include <map>
#include <string>
#include <vector>

#include "core/engine_settings.h"
#include "core/lane_config.h"
#include "core/plc_config.h"
#include "core/security_config.h"
#include "core/verification_config.h"

namespace rangex {

// How long the store keeps what (plant.yaml `retention:`). HACCP records (9 CFR 417.5) are
// kept for the plant's required period; images may go sooner, the record staying.
struct RetentionSettings {
  double days = 730;         // every record (decisions, fragments, audit entries)
  double images_days = 730;  // images of rejected and not-inspected fillets (<= days)
  double every_h = 1;        // how often rangexd runs a pass
};

struct PlantConfig {
  std::string name = "plant";
  std::string calibration_id = "dissertation-default";
  std::string backend = "auto";  // auto | cpu | opencl | vulkan
  std::string device;            // which device: an index or a name substring (empty: first)
  std::string listen = "127.0.0.1:50051";
  std::string http = "127.0.0.1:8080";  // the dashboard and /metrics; "off": none
  std::string storage = "rangex-data";
  // The plant-wide PostgreSQL every decision and record is forwarded to (a libpq connection
  // string; "" : none, the server's own store only), and the id this server's records carry
  // there ("" : the host name). docs/plant-wide.md.
  std::string results_db;
  std::string server_id;
  // After a failure to reach it, the forwarder retries after 1 s, doubling up to this.
  double results_db_retry_max_s = 30;
  EngineSettings engine;    // the `server:` section
  SecurityConfig security;  // the `security:` section
  RetentionSettings retention;
  PlcConfig plc;                    // the `plc:` section (positive release to the line's PLC)
  VerificationConfig verification;  // the `verification:` section
  std::vector<LaneConfig> lanes;
  // One plant file for several servers: each lane may name the server that runs it (a lane's
  // `server:` key; every lane or none). Empty: every lane is this server's.
  std::map<int, std::string> lane_servers;

  const LaneConfig& lane(int id) const;  // throws Error for an unknown lane
};

// The plant as server `server_id` runs it: the lanes the plant file assigns to it (all of
// them when it assigns none). Throws Error when it assigns lanes to servers but none to this
// one, naming the servers it does name.
PlantConfig plant_for_server(const PlantConfig& plant, const std::string& server_id);

PlantConfig load_plant_config(const std::string& path);
PlantConfig parse_plant_config(const std::string& yaml_text, const std::string& origin);
PlantConfig default_plant_config(int lanes);

// A calibration set for one lane (its cameras, laser_plane, xray and encoder_step_mm
// sections, as in plant.yaml) applied over `base`; refused like plant.yaml, naming the key.
LaneConfig apply_lane_calibration(const LaneConfig& base, const std::string& yaml,
                                  const std::string& origin);
// An inspection.learned section on its own (a learned-settings version), refused like
// plant.yaml, naming the key.
LearnedDetection parse_learned_detection(const std::string& yaml, const std::string& origin);
// The section as plant.yaml's inspection.learned holds it (full precision), without the
// `learned:` key; parse_learned_detection reads it back.
std::string learned_detection_yaml(const LearnedDetection& learned);

// The calibration sections of one lane as apply_lane_calibration reads them (full precision).
std::string lane_calibration_yaml(const LaneConfig& lane);

}  // namespace rangex
