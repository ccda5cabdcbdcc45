#include "core/plant_config.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>

#include "core/config_yaml.h"
#include "core/error.h"
#include "core/host_port.h"
#include "core/size_limits.h"

namespace rangex {

namespace {

void read_plc(const ConfigNode& n, PlcConfig& c) {
  n.only_keys({"address", "unit_id", "heartbeat_register", "lane_state_base", "ring_head_register",
               "ring_base", "ring_slots", "reject_station_mm", "margin_mm", "heartbeat_ms",
               "timeout_ms"});
  if (!n.has("address")) n.bad("missing key 'address' (host:port of the PLC's Modbus TCP server)");
  n.get("address", c.address);
  const auto colon = c.address.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == c.address.size())
    n.at("address").bad("must be host:port (got '" + c.address + "')");
  if (port_of(c.address) < 1)
    n.at("address").bad("the port must be a number 1..65535 (got '" + c.address + "')");
  n.get("unit_id", c.unit_id);
  if (c.unit_id < 0 || c.unit_id > 247) n.at("unit_id").bad("must be 0..247");
  for (const char* k :
       {"heartbeat_register", "lane_state_base", "ring_head_register", "ring_base"}) {
    int v = 0;
    n.get(k, v);
    if (n.has(k) && (v < 0 || v > 65535)) n.at(k).bad("must be a register 0..65535");
  }
  n.get("heartbeat_register", c.heartbeat_register);
  n.get("lane_state_base", c.lane_state_base);
  n.get("ring_head_register", c.ring_head_register);
  n.get("ring_base", c.ring_base);
  n.positive("ring_slots", c.ring_slots);
  if (c.ring_end() > 65536) n.at("ring_slots").bad("the ring runs past register 65535");
  n.positive("reject_station_mm", c.reject_station_mm);
  n.get("margin_mm", c.margin_mm);
  if (c.margin_mm < 0 || c.margin_mm >= c.reject_station_mm)
    n.at("margin_mm").bad("must be >= 0 and less than reject_station_mm");
  n.positive("heartbeat_ms", c.heartbeat_ms);
  n.positive("timeout_ms", c.timeout_ms);
  // Past a minute the line cannot wait (and the timeout's microseconds would overflow).
  if (c.heartbeat_ms > 60000) n.at("heartbeat_ms").bad("must be at most 60000 (a minute)");
  if (c.timeout_ms > 60000) n.at("timeout_ms").bad("must be at most 60000 (a minute)");
  // The registers rangex writes must not overlap.
  const int lanes_end = c.lane_state_base + 2 * PlcConfig::kMaxLanes;
  if (lanes_end > 65536)
    n.at("lane_state_base").bad("the lane states (2 x 64 lanes) run past register 65535");
  auto overlaps = [](int a0, int a1, int b0, int b1) { return a0 < b1 && b0 < a1; };
  if (overlaps(c.ring_base, c.ring_end(), c.lane_state_base, lanes_end) ||
      overlaps(c.ring_base, c.ring_end(), c.heartbeat_register, c.heartbeat_register + 1) ||
      overlaps(c.ring_base, c.ring_end(), c.ring_head_register, c.ring_head_register + 1) ||
      overlaps(c.lane_state_base, lanes_end, c.heartbeat_register, c.heartbeat_register + 1) ||
      overlaps(c.lane_state_base, lanes_end, c.ring_head_register, c.ring_head_register + 1) ||
      c.heartbeat_register == c.ring_head_register)
    n.bad("the heartbeat, lane state (2 x 64 lanes), ring head and ring registers overlap");
}

void read_engine(const ConfigNode& n, EngineSettings& e) {
  n.only_keys({"queue_lines", "batch_lines", "batch_wait_ms", "inspectors", "dedup_window",
               "auto_reset", "idle_close_s", "stall_s", "exit_after_s", "drain_timeout_s",
               "verify_fraction", "stream_idle_s", "store_reserve_mb", "max_subscriptions",
               "max_ingest_streams", "stream_gives_way_s", "grpc_memory_mb"});
  int queue = int(e.queue_lines);
  n.positive("queue_lines", queue);
  if (queue > 1 << 20) n.at("queue_lines").bad("must be <= 1048576");
  e.queue_lines = size_t(queue);
  n.positive("batch_lines", e.batch_lines);
  n.positive("batch_wait_ms", e.batch_wait_ms);
  n.positive("inspectors", e.inspectors);
  if (e.inspectors > 64) n.at("inspectors").bad("must be <= 64");
  n.positive("dedup_window", e.dedup_window);
  if (e.dedup_window > 1 << 24) n.at("dedup_window").bad("must be <= 16777216");
  n.get("auto_reset", e.auto_reset);
  n.positive("idle_close_s", e.idle_close_s);
  n.positive("stall_s", e.stall_s);
  n.get("exit_after_s", e.exit_after_s);
  if (e.exit_after_s < 0) n.at("exit_after_s").bad("must be >= 0 (0: never)");
  n.positive("drain_timeout_s", e.drain_timeout_s);
  n.positive("stream_idle_s", e.stream_idle_s);
  n.positive("max_subscriptions", e.max_subscriptions);
  if (e.max_subscriptions > 10000) n.at("max_subscriptions").bad("must be <= 10000");
  n.positive("max_ingest_streams", e.max_ingest_streams);
  if (e.max_ingest_streams > 10000) n.at("max_ingest_streams").bad("must be <= 10000");
  n.positive("stream_gives_way_s", e.stream_gives_way_s);
  n.get("grpc_memory_mb", e.grpc_memory_mb);
  if (e.grpc_memory_mb < 16 || e.grpc_memory_mb > 1 << 20)
    n.at("grpc_memory_mb").bad("must be 16..1048576 (MB)");
  n.get("store_reserve_mb", e.store_reserve_mb);
  if (!(e.store_reserve_mb >= 0)) n.at("store_reserve_mb").bad("must be >= 0 (0: no warning)");
  n.get("verify_fraction", e.verify_fraction);
  if (!(e.verify_fraction >= 0 && e.verify_fraction <= 1))
    n.at("verify_fraction").bad("must be between 0 and 1");
}

Role read_role(const ConfigNode& n) {
  const std::string s = n.str();
  const auto r = parse_role(s);
  if (!r || *r == Role::none)
    n.bad("must be one of viewer, operator, engineer, admin (got '" + s + "')");
  return *r;
}

void read_security(const ConfigNode& n, SecurityConfig& s) {
  n.only_keys({"tls", "identities", "tokens", "anonymous", "insecure"});
  if (n.has("tls")) {
    const ConfigNode t = n.at("tls");
    t.only_keys({"cert", "key", "client_ca"});
    t.get("cert", s.tls_cert);
    t.get("key", s.tls_key);
    t.get("client_ca", s.client_ca);
    if (s.tls_cert.empty() != s.tls_key.empty())
      t.bad("needs both cert and key (the server's certificate chain and its private key)");
    if (!s.client_ca.empty() && s.tls_cert.empty())
      t.bad("client_ca needs the server's own cert and key: client certificates are TLS");
  }
  if (n.has("identities")) {
    const ConfigNode ids = n.at("identities");
    if (!ids.node.IsMap()) ids.bad("expected a mapping of certificate common name to role");
    for (const auto& kv : ids.node) {
      if (!kv.first.IsScalar()) ids.bad("has a name that is not a plain string");
      const auto name = kv.first.as<std::string>();
      if (!s.identities.emplace(name, read_role(ids.at(name))).second)
        ids.bad("duplicate identity '" + name + "'");
    }
    if (!s.identities.empty() && s.client_ca.empty())
      ids.bad(
          "names certificate identities but tls.client_ca is not set: no client "
          "certificate could be verified");
  }
  if (n.has("tokens")) {
    const ConfigNode list = n.at("tokens");
    if (!list.node.IsSequence()) list.bad("expected a list of {name, role, sha256}");
    std::set<std::string> names, hashes;
    for (size_t i = 0; i < list.node.size(); ++i) {
      const ConfigNode t = list.item(i);
      t.only_keys({"name", "role", "sha256"});
      for (const char* k : {"name", "role", "sha256"})
        if (!t.has(k)) t.bad(std::string("missing key '") + k + "'");
      TokenEntry e{t.at("name").str(), read_role(t.at("role")), t.at("sha256").str()};
      if (e.name.empty()) t.at("name").bad("must not be empty");
      const bool hex = e.sha256.size() == 64 &&
                       e.sha256.find_first_not_of("0123456789abcdef") == std::string::npos;
      if (!hex)
        t.at("sha256").bad(
            "must be the token's SHA-256 as 64 lower-case hex digits "
            "(rangexctl token prints it)");
      if (!names.insert(e.name).second) t.at("name").bad("duplicate token name '" + e.name + "'");
      if (!hashes.insert(e.sha256).second) t.at("sha256").bad("the same token is listed twice");
      s.tokens.push_back(std::move(e));
    }
    if (!s.tokens.empty() && !s.tls())
      list.bad(
          "bearer tokens need tls: a token sent in clear can be replayed by anyone on "
          "the path");
  }
  if (n.has("anonymous")) {
    const ConfigNode a = n.at("anonymous");
    const auto r = parse_role(a.str());
    if (!r) a.bad("must be one of none, viewer, operator, engineer, admin (got '" + a.str() + "')");
    s.anonymous = *r;
  }
  n.get("insecure", s.insecure);
}
}  // namespace

const LaneConfig& PlantConfig::lane(int id) const {
  for (const auto& l : lanes)
    if (l.id == id) return l;
  fail_not_found("unknown lane ", id, " (plant '", name, "' has ", lanes.size(), " lanes)");
}

PlantConfig parse_plant_config(const std::string& text, const std::string& origin) {
  const YAML::Node root = load_yaml(text, origin);
  const ConfigNode top{root, "", &origin};
  top.only_keys({"plant", "server", "security", "retention", "plc", "verification", "lane_defaults",
                 "lanes"});
  PlantConfig p;
  if (top.has("plant")) {
    const ConfigNode n = top.at("plant");
    n.only_keys({"name", "calibration_id", "backend", "device", "listen", "http", "storage",
                 "results_db", "server_id", "results_db_retry_max_s"});
    n.get("name", p.name);
    n.get("calibration_id", p.calibration_id);
    n.get("backend", p.backend);
    if (p.backend != "auto" && p.backend != "cpu" && p.backend != "opencl" && p.backend != "vulkan")
      n.at("backend").bad("must be one of auto, cpu, opencl, vulkan (got '" + p.backend + "')");
    n.get("device", p.device);
    n.get("listen", p.listen);
    n.get("http", p.http);
    if (p.http != "off" && port_of(p.http) < 0)
      n.at("http").bad("must be host:port (a port 0..65535; 0: any free one) or off (got '" +
                       p.http + "')");
    n.get("storage", p.storage);
    n.get("results_db", p.results_db);
    // A password in plant.yaml is a password every reader of the file has: libpq's password
    // file (PGPASSFILE, ~/.pgpass or passfile=) keeps it apart.
    if (p.results_db.find("password") != std::string::npos ||
        (p.results_db.find("://") != std::string::npos &&
         p.results_db.find('@') != std::string::npos &&
         p.results_db.substr(0, p.results_db.find('@')).find(':', p.results_db.find("://") + 3) !=
             std::string::npos))
      n.at("results_db")
          .bad(
              "holds a password: put it in a password file (PGPASSFILE, ~/.pgpass or "
              "passfile=...)");
    n.get("server_id", p.server_id);
    for (char c : p.server_id)
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.'))
        n.at("server_id").bad("'" + p.server_id + "': letters, digits, '-', '_' and '.' only");
    n.get("results_db_retry_max_s", p.results_db_retry_max_s);
    if (!(p.results_db_retry_max_s >= 1 && p.results_db_retry_max_s <= 3600))
      n.at("results_db_retry_max_s").bad("must be within 1..3600 s (the first retry waits 1 s)");
  }
  if (top.has("server")) read_engine(top.at("server"), p.engine);
  if (top.has("security")) read_security(top.at("security"), p.security);
  if (top.has("retention")) {
    const ConfigNode n = top.at("retention");
    RetentionSettings& r = p.retention;
    n.only_keys({"days", "images_days", "every_h"});
    n.get("days", r.days);
    if (!(r.days >= 1)) n.at("days").bad("must be >= 1 (records are kept at least a day)");
    r.images_days = r.days;
    n.get("images_days", r.images_days);
    if (!(r.images_days >= 1 && r.images_days <= r.days))
      n.at("images_days").bad("must be between 1 and days (" + std::to_string(r.days) + ")");
    n.positive("every_h", r.every_h);
  }
  if (top.has("plc")) read_plc(top.at("plc"), p.plc);
  if (top.has("verification")) {
    const ConfigNode n = top.at("verification");
    n.only_keys({"every_h", "fillets", "tolerance_mm"});
    n.get("every_h", p.verification.every_h);
    if (p.verification.every_h < 0) n.at("every_h").bad("must be >= 0 (0: no schedule)");
    n.positive("fillets", p.verification.fillets);
    n.positive("tolerance_mm", p.verification.tolerance_mm);
  }
  std::optional<ConfigNode> defaults;
  if (top.has("lane_defaults")) defaults = top.at("lane_defaults");
  if (!top.has("lanes")) top.bad("missing key 'lanes'");
  const ConfigNode lanes = top.at("lanes");
  if (!lanes.node.IsSequence() || lanes.node.size() == 0) lanes.bad("expected a non-empty list");
  std::set<int> seen;
  std::set<std::string> sensors;
  for (size_t i = 0; i < lanes.node.size(); ++i) {
    const ConfigNode ln = lanes.item(i);
    ln.only_keys({"id", "server", "frame", "encoder_step_mm", "cameras", "laser_plane", "xray",
                  "stripe", "rectify", "fusion", "inspection", "sources"});
    if (!ln.has("id")) ln.bad("missing key 'id'");
    const int id = ln.at("id").integer();
    if (id < 0) ln.at("id").bad("must be >= 0");
    LaneConfig l = read_lane(ln, defaults ? &*defaults : nullptr, default_lane_config(id));
    // A lane's sensors are its own: never in lane_defaults.
    if (ln.has("sources")) read_sources(ln.at("sources"), l.sources);
    if (!seen.insert(l.id).second)
      lanes.item(i).at("id").bad("duplicate lane id " + std::to_string(l.id));
    for (const std::string& d : l.sources.devices())
      if (!sensors.insert(d).second)
        ln.at("sources").bad("device '" + d + "' already belongs to another lane");
    if (p.plc.enabled() && l.id >= PlcConfig::kMaxLanes)
      ln.at("id").bad("lane ids go up to " + std::to_string(PlcConfig::kMaxLanes - 1) +
                      " with a PLC (its lane state registers)");
    if (ln.has("server")) {
      const std::string server = ln.at("server").str();
      if (server.empty() || server.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQ"
                                                     "RSTUVWXYZ0123456789-_.") != std::string::npos)
        ln.at("server").bad("'" + server + "': a server id (letters, digits, '-', '_' and '.')");
      p.lane_servers[l.id] = server;
    }
    if (!p.lane_servers.empty() && p.lane_servers.size() != i + 1)
      ln.bad("every lane names its server (key 'server') or none does");
    p.lanes.push_back(std::move(l));
  }
  return p;
}

PlantConfig plant_for_server(const PlantConfig& plant, const std::string& server_id) {
  if (plant.lane_servers.empty()) return plant;
  PlantConfig p = plant;
  p.lanes.clear();
  std::set<std::string> named;
  for (const LaneConfig& l : plant.lanes) {
    const std::string& s = plant.lane_servers.at(l.id);
    named.insert(s);
    if (s == server_id) p.lanes.push_back(l);
  }
  if (p.lanes.empty()) {
    std::string list;
    for (const std::string& s : named) list += (list.empty() ? "" : ", ") + s;
    fail("plant '", plant.name, "' assigns no lane to server '", server_id, "' (its lanes name ",
         list, "): start rangexd with --server-id, or set plant.server_id");
  }
  return p;
}

PlantConfig load_plant_config(const std::string& path) {
  std::ifstream in(path);
  if (!in) fail(path, ": cannot open plant configuration");
  // Sized before it is read: a huge file is refused without taking its memory.
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(path, ec);
  if (!ec) check_size(path + " (the plant configuration)", size_t(bytes), kMaxPlantConfigBytes);
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_plant_config(ss.str(), path);
}

PlantConfig default_plant_config(int lanes) {
  PlantConfig p;
  for (int i = 0; i < lanes; ++i) p.lanes.push_back(default_lane_config(i));
  return p;
}

}  // namespace rangex
