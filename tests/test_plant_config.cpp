// plant.yaml loading: the shipped default parses; bad values are refused naming the key.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/plant_config.h"
#include "core/size_limits.h"

using namespace rangex;

namespace {
std::string error_of(const std::string& yaml) {
  try {
    parse_plant_config(yaml, "test.yaml");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}
// Why a calibration set uploaded for a lane of the shipped rig is refused ("" if taken).
std::string calibration_error_of(const std::string& yaml) {
  try {
    apply_lane_calibration(default_plant_config(1).lanes[0], yaml, "upload");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(PlantConfig, HugeDocumentsAreRefusedBeforeParsing) {
  // A 50 MB plant.yaml aborted rangexd with bad_alloc after 35 s at 7.9 GB: now its size is
  // read first, and YAML text of any origin is bounded before it is parsed.
  const std::string path = ::testing::TempDir() + "/huge_plant.yaml";
  {
    std::ofstream out(path);
    const std::string line = "lanes: [{id: 0}, {id: 1}, {id: 2}, {id: 3}, {id: 4}, {id: 5}]\n";
    for (size_t n = 0; n < (size_t(50) << 20); n += line.size()) out << line;
  }
  try {
    load_plant_config(path);
    ADD_FAILURE() << "a 50 MB plant configuration was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("is 50.0 MiB, more than the 2.0 MiB allowed"),
              std::string::npos)
        << e.what();
  }
  std::remove(path.c_str());
  const std::string big(kMaxYamlBytes + 1, '#');
  EXPECT_NE(error_of(big).find("test.yaml is 2.0 MiB, more than the 2.0 MiB allowed"),
            std::string::npos)
      << error_of(big);
  try {
    parse_learned_detection(big, "learned settings 'x'");
    ADD_FAILURE() << "learned settings of 2 MiB were parsed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("learned settings 'x' is"), std::string::npos);
  }
}

TEST(PlantConfig, ShippedDefaultLoads) {
  const PlantConfig p = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  ASSERT_EQ(p.lanes.size(), 4u);
  EXPECT_EQ(p.listen.rfind("127.0.0.1:", 0), 0u) << "listens on loopback by default";
  const LaneConfig& l = p.lane(2);
  EXPECT_DOUBLE_EQ(l.cameras[0].model.intrinsics().fx, 1780.10076);
  EXPECT_DOUBLE_EQ(l.cameras[1].model.distortion().k2, 5.38559);
  EXPECT_EQ(l.stripe.method, StripeMethod::kModified);
  // The two cameras sit on opposite sides of the laser plane.
  EXPECT_GT(l.cameras[0].model.center().y * l.cameras[1].model.center().y, -1e9);
  EXPECT_LT(l.cameras[0].model.center().y * l.cameras[1].model.center().y, 0);
  EXPECT_THROW(p.lane(9), NotFound);
  EXPECT_EQ(p.engine.queue_lines, 2048u);
  EXPECT_TRUE(p.engine.auto_reset);
  EXPECT_DOUBLE_EQ(p.engine.exit_after_s, 60);
}

TEST(PlantConfig, LaneOverridesSectionOfDefaults) {
  const PlantConfig p = parse_plant_config(R"(
lane_defaults:
  stripe: {method: gaussian3, min_peak: 50}
lanes:
  - id: 0
  - id: 1
    stripe: {method: binary}
)",
                                           "t");
  EXPECT_EQ(p.lane(0).stripe.method, StripeMethod::kGaussian3);
  EXPECT_EQ(p.lane(0).stripe.min_peak, 50);
  EXPECT_EQ(p.lane(1).stripe.method, StripeMethod::kBinary);
  EXPECT_EQ(p.lane(1).stripe.min_peak, 40);  // the lane's own section replaces the default
}

TEST(PlantConfig, BadInputNamesKeyAndReason) {
  EXPECT_NE(error_of("lanes: [ {id: 0} \n foo").find("not valid YAML"), std::string::npos);
  EXPECT_NE(
      error_of(
          "lanes:\n  - id: 0\n  - id: 1\n    cameras:\n      - intrinsics: {fx: -5}\n      - {}\n")
          .find("lanes[1].cameras[0].intrinsics.fx: must be > 0"),
      std::string::npos);
  EXPECT_NE(
      error_of("lanes:\n  - id: 0\n    cameras:\n      - intrinsics: {fx: .nan}\n      - {}\n")
          .find("intrinsics.fx: must be finite"),
      std::string::npos);
  EXPECT_NE(error_of("lanes:\n  - id: 0\n    stripe: {method: median}\n").find("stripe.method"),
            std::string::npos);
  EXPECT_NE(error_of("lanes:\n  - id: 0\n    strpe: {}\n").find("unknown key 'strpe'"),
            std::string::npos);
  EXPECT_NE(error_of("lanes:\n  - id: 0\n  - id: 0\n").find("duplicate lane id 0"),
            std::string::npos);
  EXPECT_NE(
      error_of(
          "lanes:\n  - id: 0\n    cameras:\n      - rotation: [1,0,0,0,1,0,0,0,2]\n      - {}\n")
          .find("not a proper rotation"),
      std::string::npos);
  EXPECT_NE(error_of("plant: {backend: cuda}\nlanes: [{id: 0}]\n").find("plant.backend"),
            std::string::npos);
  EXPECT_NE(error_of("plant: {name: x}\n").find("missing key 'lanes'"), std::string::npos);
  EXPECT_NE(
      error_of("server: {stall_s: 0}\nlanes: [{id: 0}]\n").find("server.stall_s: must be > 0"),
      std::string::npos);
  EXPECT_NE(error_of("server: {stall_s: 1}\nlanes: [{id: 0}]\nserver: {stall_s: 2}\n")
                .find("duplicate key 'server'"),
            std::string::npos);
  // A bound of `server:`: its default, a value taken, and values refused naming the key.
  const auto bound = [&](const std::string& key, int EngineSettings::*field, int fallback,
                         int taken, std::initializer_list<const char*> refused) {
    const auto with = [&](const std::string& v) {
      return "server: {" + key + ": " + v + "}\nlanes: [{id: 0}]\n";
    };
    EXPECT_EQ(parse_plant_config("lanes: [{id: 0}]\n", "test").engine.*field, fallback) << key;
    EXPECT_EQ(parse_plant_config(with(std::to_string(taken)), "test").engine.*field, taken) << key;
    for (const char* bad : refused)
      EXPECT_NE(error_of(with(bad)).find("server." + key + ": "), std::string::npos)
          << key << ": " << bad;
  };
  bound("max_subscriptions", &EngineSettings::max_subscriptions, 64, 8,
        {"0", "-1", "10001", "many"});
  bound("max_ingest_streams", &EngineSettings::max_ingest_streams, 256, 4,
        {"0", "-1", "10001", "all"});
  bound("grpc_memory_mb", &EngineSettings::grpc_memory_mb, 256, 16,
        {"0", "15", "-1", "1048577", "lots"});
  EXPECT_EQ(parse_plant_config("lanes: [{id: 0}]\n", "test").engine.stream_gives_way_s, 30);
  EXPECT_EQ(parse_plant_config("server: {stream_gives_way_s: 2.5}\nlanes: [{id: 0}]\n", "test")
                .engine.stream_gives_way_s,
            2.5);
  for (const char* bad : {"0", "-1", "soon"})
    EXPECT_NE(error_of("server: {stream_gives_way_s: " + std::string(bad) + "}\nlanes: [{id: 0}]\n")
                  .find("server.stream_gives_way_s: "),
              std::string::npos)
        << bad;
  EXPECT_NE(error_of("server: {auto_reset: maybe}\nlanes: [{id: 0}]\n")
                .find("server.auto_reset: expected true or false"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {encoder_horizon_lines: -1}}]\n")
                .find("inspection.encoder_horizon_lines: must be > 0"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {attenuation_degree: 3}}]\n")
                .find("inspection.attenuation_degree: must be 1 (a line) or 2"),
            std::string::npos);
  EXPECT_NE(
      error_of("lanes:\n  - id: 0\n    frame: {width: 640, height: 3}\n").find("out of range"),
      std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {matched_clip: 0.2}}]\n")
                .find("inspection.matched_clip: must be within 0.5..100 robust spreads"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {matched_enclosure: 4}}]\n")
                .find("inspection.matched_enclosure: expected true or false"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {matched_needles_mm: [2, 0.5]}}]\n")
                .find("inspection.matched_needles_mm: needle lengths must be within 1..6 mm"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {matched_needle_diameter_mm: 3}}]\n")
                .find("inspection.matched_needle_diameter_mm: must be within 0.2..2 mm"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {matched_needle_diameter_mm: [0.6, 3]}}]\n")
                .find("inspection.matched_needle_diameter_mm: must be within 0.2..2 mm"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {matched_needle_diameter_mm: []}}]\n")
                .find("inspection.matched_needle_diameter_mm: expected a diameter or a list"),
            std::string::npos);
  // That a detection must add attenuation is the plant's choice, off unless it says so.
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {require_added_attenuation: 0.5}}]\n")
                .find("inspection.require_added_attenuation: expected true or false"),
            std::string::npos);
  EXPECT_FALSE(parse_plant_config("lanes: [{id: 0}]\n", "test")
                   .lane(0)
                   .inspection.require_added_attenuation);
  EXPECT_TRUE(parse_plant_config(
                  "lanes: [{id: 0, inspection: {require_added_attenuation: true}}]\n", "test")
                  .lane(0)
                  .inspection.require_added_attenuation);
  // One diameter or a bank of widths.
  EXPECT_EQ(parse_plant_config("lanes: [{id: 0}]\n", "test")
                .lane(0)
                .inspection.matched_needle_diameters_mm,
            std::vector<double>{0.6});
  EXPECT_EQ(parse_plant_config(
                "lanes: [{id: 0, inspection: {matched_needle_diameter_mm: [0.6, 1.0]}}]\n", "test")
                .lane(0)
                .inspection.matched_needle_diameters_mm,
            (std::vector<double>{0.6, 1.0}));
}

TEST(PlantConfig, ThePlantWideDatabaseTakesNoPasswordInTheFile) {
  const PlantConfig ok = parse_plant_config(
      "plant: {results_db: 'host=db.plant port=5432 dbname=rangex user=line1 sslmode=verify-full', "
      "server_id: line-1.hall_2}\nlanes: [{id: 0}]\n",
      "test");
  EXPECT_EQ(ok.results_db, "host=db.plant port=5432 dbname=rangex user=line1 sslmode=verify-full");
  EXPECT_EQ(ok.server_id, "line-1.hall_2");
  EXPECT_TRUE(parse_plant_config("lanes: [{id: 0}]\n", "test").results_db.empty());
  for (const char* bad : {"host=db password=secret", "postgresql://line1:secret@db/rangex"})
    EXPECT_NE(error_of(std::string("plant: {results_db: '") + bad + "'}\nlanes: [{id: 0}]\n")
                  .find("plant.results_db: holds a password"),
              std::string::npos)
        << bad;
  EXPECT_NO_THROW(parse_plant_config(
      "plant: {results_db: 'postgresql://line1@db/rangex'}\nlanes: [{id: 0}]\n", "test"));
  EXPECT_NE(error_of("plant: {server_id: 'a b'}\nlanes: [{id: 0}]\n").find("plant.server_id"),
            std::string::npos);
}

TEST(PlantConfig, TheForwardersLongestWaitBetweenRetriesIsThePlants) {
  EXPECT_EQ(parse_plant_config("lanes: [{id: 0}]\n", "test").results_db_retry_max_s, 30);
  EXPECT_EQ(parse_plant_config("plant: {results_db_retry_max_s: 300}\nlanes: [{id: 0}]\n", "test")
                .results_db_retry_max_s,
            300);
  for (const char* bad : {"0.5", "0", "-1", "7200", ".nan"})
    EXPECT_NE(
        error_of(std::string("plant: {results_db_retry_max_s: ") + bad + "}\nlanes: [{id: 0}]\n")
            .find("plant.results_db_retry_max_s: must be"),  // within 1..3600 s; finite
        std::string::npos)
        << bad;
}

TEST(PlantConfig, OnePlantFileAssignsEachServerItsLanes) {
  const PlantConfig p = parse_plant_config(
      "lanes: [{id: 0, server: line-1}, {id: 1, server: line-1}, {id: 5, server: line-2.b}]\n",
      "test");
  ASSERT_EQ(p.lane_servers.size(), 3u);
  const PlantConfig one = plant_for_server(p, "line-1");
  ASSERT_EQ(one.lanes.size(), 2u);
  EXPECT_EQ(one.lanes[1].id, 1);
  const PlantConfig two = plant_for_server(p, "line-2.b");
  ASSERT_EQ(two.lanes.size(), 1u);
  EXPECT_EQ(two.lanes[0].id, 5);
  try {
    plant_for_server(p, "line-3");
    FAIL() << "a server with no lane was given the plant";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("assigns no lane to server 'line-3' (its lanes name "
                                         "line-1, line-2.b)"),
              std::string::npos)
        << e.what();
  }
  // Without lanes naming servers, every server runs every lane (one server, as before).
  const PlantConfig all = parse_plant_config("lanes: [{id: 0}, {id: 1}]\n", "test");
  EXPECT_EQ(plant_for_server(all, "anyone").lanes.size(), 2u);
  // Every lane names its server or none does; a server's name is an id.
  for (const char* bad :
       {"lanes: [{id: 0, server: a}, {id: 1}]\n", "lanes: [{id: 0}, {id: 1, server: a}]\n"})
    EXPECT_NE(error_of(bad).find("every lane names its server"), std::string::npos) << bad;
  EXPECT_NE(error_of("lanes: [{id: 0, server: 'a b'}]\n").find("lanes[0].server"),
            std::string::npos)
      << error_of("lanes: [{id: 0, server: 'a b'}]\n");
}

TEST(PlantConfig, RegistrationRoundTripsAndIsChecked) {
  LaneConfig lane = parse_plant_config("lanes: [{id: 0}]\n", "t").lane(0);
  lane.xray.delay_lines = 50;
  lane.xray.measured_delay_lines = 50.32;
  lane.xray.plane_alpha_deg = 0.31;
  lane.xray.plane_beta_deg = -0.42;
  const LaneConfig back = apply_lane_calibration(lane, lane_calibration_yaml(lane), "t");
  EXPECT_DOUBLE_EQ(back.xray.measured_delay_lines, 50.32);
  EXPECT_DOUBLE_EQ(back.xray.plane_alpha_deg, 0.31);
  EXPECT_DOUBLE_EQ(back.xray.plane_beta_deg, -0.42);
  EXPECT_NE(error_of("lanes: [{id: 0, xray: {delay_lines: 50, measured_delay_lines: 53}}]\n")
                .find("xray.measured_delay_lines: must be within one line of delay_lines"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, xray: {plane_beta_deg: .nan}}]\n").find("plane_beta_deg"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, xray: {plane_alpha_deg: 12}}]\n")
                .find("xray.plane_alpha_deg: must be within +-5 degrees"),
            std::string::npos);
}

TEST(PlantConfig, DualEnergyIsReadCheckedAndRoundTrips) {
  const LaneConfig single = parse_plant_config("lanes: [{id: 0}]\n", "t").lane(0);
  EXPECT_EQ(single.xray.energies, 1);
  const LaneConfig dual =
      parse_plant_config(
          "lanes: [{id: 0, xray: {energies: 2, sandwich: {kvp: 90, filter_cu_mm: 0.6, "
          "low_photons: 160000}}}]\n",
          "t")
          .lane(0);
  EXPECT_EQ(dual.xray.energies, 2);
  EXPECT_EQ(dual.xray.sandwich.kvp, 90);
  EXPECT_EQ(dual.xray.sandwich.filter_cu_mm, 0.6);
  EXPECT_EQ(dual.xray.sandwich.front_csi_mm, SandwichDetector{}.front_csi_mm);
  const LaneConfig back = apply_lane_calibration(single, lane_calibration_yaml(dual), "t");
  EXPECT_EQ(back.xray.energies, 2);
  EXPECT_EQ(back.xray.sandwich.kvp, 90);
  EXPECT_EQ(dual.xray.sandwich.low_photons, 160000);
  EXPECT_EQ(back.xray.sandwich.low_photons, 160000);
  EXPECT_NE(error_of("lanes: [{id: 0, xray: {energies: 2, sandwich: {low_photons: 0}}}]\n")
                .find("low_photons"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {soft_density_sigma: -0.1}}]\n")
                .find("soft_density_sigma: must be within 0..0.5"),
            std::string::npos);
  EXPECT_NE(
      error_of("lanes: [{id: 0, xray: {energies: 3}}]\n").find("xray.energies: must be 1 or 2"),
      std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, xray: {sandwich: {kvp: 90}}}]\n")
                .find("xray.sandwich: is for energies: 2"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, xray: {energies: 2, sandwich: {kvp: 400}}}]\n")
                .find("kvp 400 must be 30..150 kV"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, xray: {energies: 2, sandwich: {kv: 90}}}]\n")
                .find("unknown key 'kv'"),
            std::string::npos);
  // The wedge's fit (rangexctl calib dual-energy writes it) round-trips whole.
  LaneConfig fitted = dual;
  fitted.xray.has_dual_energy = true;
  fitted.xray.dual_energy_fitted_on = "/scans/wedge";
  kernel::DualEnergyK& k = fitted.xray.dual_energy;
  for (int i = 0; i < DE_TERMS; ++i) k.low[i] = 0.1 * i - 0.7, k.high[i] = 1.0 / (i + 3);
  for (int i = 0; i < 9; ++i) k.minv[i] = i - 4.5;
  for (int i = 0; i < 6; ++i) k.basis[i] = 0.25 * i - 0.2;
  k.var_a = 1e-3, k.var_b = 2e-4, k.gain_low = 0.1, k.gain_high = 0.6, k.var_e_low = 4;
  k.var_e_high = 5, k.var_t = 0.01;
  const std::string yaml = lane_calibration_yaml(fitted);
  const LaneConfig again = apply_lane_calibration(single, yaml, "t");
  ASSERT_TRUE(again.xray.has_dual_energy);
  EXPECT_EQ(again.xray.dual_energy_fitted_on, "/scans/wedge");
  EXPECT_EQ(0, std::memcmp(&again.xray.dual_energy, &k, sizeof k));
  const std::string section = yaml.substr(yaml.find("  dual_energy:"));
  EXPECT_EQ(lane_calibration_yaml(again).substr(yaml.find("  dual_energy:")), section);
  EXPECT_NE(error_of("lanes: [{id: 0, xray: {dual_energy: {}}}]\n")
                .find("xray.dual_energy: is for energies: 2"),
            std::string::npos);
  EXPECT_NE(error_of("lanes: [{id: 0, xray: {energies: 2, dual_energy: {low: [1, 2]}}}]\n")
                .find("xray.dual_energy.low: expected a list of 21 numbers"),
            std::string::npos);
  std::string no_gain = yaml.substr(yaml.find("xray:"));
  const size_t g = no_gain.find("gain_low: ");
  no_gain.replace(g, no_gain.find('\n', g) - g, "gain_low: 0");
  const std::string bad_gain = "lane_defaults:\n" + [&] {
    std::string out;
    std::istringstream in(no_gain);
    for (std::string line; std::getline(in, line);) out += "  " + line + "\n";
    return out;
  }() + "lanes: [{id: 0}]\n";
  EXPECT_NE(error_of(bad_gain).find("dual_energy.gain_low: must be > 0"), std::string::npos)
      << error_of(bad_gain);
  // How a lane inspects: laser (the default), no_laser, low_line, laser_and_low_line;
  // nothing else.
  EXPECT_EQ(single.inspection.dual_energy, DualEnergyMethod::kLaser);
  EXPECT_EQ(parse_plant_config("lanes: [{id: 0, inspection: {dual_energy: no_laser}}]\n", "t")
                .lane(0)
                .inspection.dual_energy,
            DualEnergyMethod::kNoLaser);
  EXPECT_EQ(
      parse_plant_config("lanes: [{id: 0, inspection: {dual_energy: laser_and_low_line}}]\n", "t")
          .lane(0)
          .inspection.dual_energy,
      DualEnergyMethod::kLaserAndLowLine);
  EXPECT_NE(error_of("lanes: [{id: 0, inspection: {dual_energy: both}}]\n")
                .find("'both': expected laser, no_laser, low_line or laser_and_low_line"),
            std::string::npos);
}

TEST(PlantConfig, SecuritySectionIsReadAndChecked) {
  const std::string lanes = "lanes: [{id: 0}]\n";
  const std::string sha(64, 'a');
  const PlantConfig p = parse_plant_config(lanes + R"(
security:
  tls: {cert: s.crt, key: s.key, client_ca: ca.crt}
  identities: {line-1: operator, qa: viewer}
  tokens:
    - {name: mes, role: engineer, sha256: )" + sha +
                                               R"(}
)",
                                           "test.yaml");
  EXPECT_TRUE(p.security.tls());
  EXPECT_EQ(p.security.identities.at("line-1"), Role::operator_);
  ASSERT_EQ(p.security.tokens.size(), 1u);
  EXPECT_EQ(p.security.tokens[0].role, Role::engineer);
  EXPECT_EQ(p.security.anonymous_role(), Role::none);  // authentication configured
  // Zero configuration: no authentication, every loopback caller is admin.
  EXPECT_EQ(parse_plant_config(lanes, "t").security.anonymous_role(), Role::admin);

  const std::pair<std::string, std::string> bad[] = {
      {"security: {tls: {cert: s.crt}}", "security.tls: needs both cert and key"},
      {"security: {tls: {client_ca: ca.crt}}", "client_ca needs the server's own cert"},
      {"security: {identities: {a: viewer}}", "tls.client_ca is not set"},
      {"security: {tls: {cert: c, key: k, client_ca: a}, identities: {a: root}}",
       "security.identities.a: must be one of viewer, operator, engineer, admin (got 'root')"},
      {"security: {tokens: [{name: a, role: viewer, sha256: " + sha + "}]}",
       "bearer tokens need tls"},
      {"security: {tls: {cert: c, key: k}, tokens: [{name: a, role: viewer, sha256: abc}]}",
       "security.tokens[0].sha256: must be the token's SHA-256"},
      {"security: {tls: {cert: c, key: k}, tokens: [{name: a, role: viewer}]}",
       "missing key 'sha256'"},
      {"security: {tls: {cert: c, key: k}, tokens: [{name: a, role: viewer, sha256: " + sha +
           "}, {name: b, role: admin, sha256: " + sha + "}]}",
       "the same token is listed twice"},
      {"security: {anonymous: everyone}", "security.anonymous: must be one of none"},
      {"security: {insecure: maybe}", "security.insecure: expected true or false"},
      {"security: {password: x}", "unknown key 'password'"},
  };
  for (const auto& [yaml, why] : bad) {
    const std::string e = error_of(lanes + yaml + "\n");
    EXPECT_NE(e.find(why), std::string::npos) << yaml << "\n -> " << e;
  }
}

TEST(PlantConfig, RetentionIsReadAndChecked) {
  const std::string lanes = "lanes: [{id: 0}]\n";
  EXPECT_DOUBLE_EQ(parse_plant_config(lanes, "t").retention.days, 730);  // 2 years
  const PlantConfig p = parse_plant_config(lanes + "retention: {days: 1095}\n", "t");
  EXPECT_DOUBLE_EQ(p.retention.images_days, 1095);  // images follow the records by default
  EXPECT_NE(error_of(lanes + "retention: {days: 0}\n").find("retention.days: must be >= 1"),
            std::string::npos);
  EXPECT_NE(error_of(lanes + "retention: {days: 30, images_days: 60}\n")
                .find("retention.images_days: must be between 1 and days"),
            std::string::npos);
  EXPECT_NE(error_of(lanes + "retention: {every_h: -1}\n").find("retention.every_h"),
            std::string::npos);
}

// A rotation with rounded digits (within the tolerance) is read as the nearest rotation, so
// that a calibration stored and read back keeps its camera where it was (found by fuzzing:
// the centre drifted by 0.5 um on each round trip).
TEST(PlantConfig, ANearRotationIsMadeExactAndRoundTrips) {
  const PlantConfig shipped = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  std::string yaml = lane_calibration_yaml(shipped.lanes[0]);
  const size_t at = yaml.find("-0.72583696");
  ASSERT_NE(at, std::string::npos) << yaml;
  yaml.replace(at, yaml.find_first_of(",]", at) - at, "-0.7258369668442386");  // 1.6e-9 off
  LaneConfig l = apply_lane_calibration(shipped.lanes[0], yaml, "rounded");
  const Vec3 c0 = l.cameras[1].model.center();
  for (int k = 0; k < 5; ++k) l = apply_lane_calibration(l, lane_calibration_yaml(l), "again");
  const Vec3 c5 = l.cameras[1].model.center();
  EXPECT_NEAR(c5.x, c0.x, 1e-9);
  EXPECT_NEAR(c5.y, c0.y, 1e-9);
  EXPECT_NEAR(c5.z, c0.z, 1e-9);
  const Mat3 R = l.cameras[1].model.rotation();
  const Mat3 I = R * R.transposed();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(I(i, j), i == j ? 1.0 : 0.0, 1e-14);
}

// Found by fuzzing: a list as a key escaped as yaml-cpp's exception instead of an Error
// naming where it is (rangexd would have died on such a plant.yaml).
TEST(PlantConfig, AKeyThatIsNotANameIsRefusedNamingWhere) {
  EXPECT_NE(error_of("lanes: [{id: 0, [0, 1]: 2}]\n")
                .find("lanes[0]: has a key that is not a plain name"),
            std::string::npos)
      << error_of("lanes: [{id: 0, [0, 1]: 2}]\n");
  const std::string why =
      calibration_error_of("laser_plane: {normal: [0, 1, 0], [0, 1, 0]: 0.05}\n");
  EXPECT_NE(why.find("laser_plane: has a key that is not a plain name"), std::string::npos) << why;
}

// A plant named with a byte that is not UTF-8 was taken, and every gRPC client then failed
// to read the server's info ("No message returned"): protobuf strings must be UTF-8, and so
// must YAML. Such a file is refused naming the line and the byte; UTF-8 names are taken.
TEST(PlantConfig, TextThatIsNotUtf8IsRefusedNamingWhere) {
  EXPECT_EQ(error_of("plant:\n  name: demo\xffplant\nlanes: [{id: 0}]\n"),
            "test.yaml: line 2: byte 0xFF is not UTF-8 (YAML is Unicode text: write names and "
            "notes in UTF-8)");
  EXPECT_NE(error_of("lanes: [{id: 0, name: \"lane \xc3\"}]\n").find("line 1: byte 0xC3"),
            std::string::npos);
  EXPECT_EQ(parse_plant_config("plant:\n  name: \"Fl\xc3\xa6sk \xe2\x82\xac\"\nlanes: [{id: 0}]\n",
                               "test.yaml")
                .name,
            "Fl\xc3\xa6sk \xe2\x82\xac");
  const std::string why = calibration_error_of("cameras: [{name: \"cam\xed\xa0\x80\"}]\n");
  EXPECT_NE(why.find("upload: line 1: byte 0xED is not UTF-8"), std::string::npos) << why;
}

// Found by fuzzing: strings in a stored calibration (camera names, where the scatter
// constants were fitted) were written unquoted and did not read back.
TEST(PlantConfig, CalibrationStringsReadBackAsWritten) {
  LaneConfig l = default_plant_config(1).lanes[0];
  l.cameras[0].name = "cam: \"left\"\nsecond line # not a comment";
  l.cameras[1].scatter_fitted_on = "fitted on 2026-11-23, rig 'B' \\ lane 0\ttab";
  const LaneConfig back = apply_lane_calibration(l, lane_calibration_yaml(l), "stored");
  EXPECT_EQ(back.cameras[0].name, l.cameras[0].name);
  EXPECT_EQ(back.cameras[1].scatter_fitted_on, l.cameras[1].scatter_fitted_on);
}

// Found by fuzzing: a camera 43 km from the lane was taken (a typo a rig cannot have).
TEST(PlantConfig, ACameraKilometresAwayIsRefused) {
  const std::string e = error_of(
      "lanes: [{id: 0, cameras: [{name: a, center_mm: [0, 414.5, 43067232.8]}, {name: b}]}]\n");
  EXPECT_NE(e.find("lanes[0].cameras[0].center_mm: is more than 10 m from the lane's origin"),
            std::string::npos)
      << e;
}

TEST(PlantConfig, LaneSourcesAreReadAndChecked) {
  const PlantConfig p = parse_plant_config(
      "lanes:\n"
      "  - id: 0\n"
      "    sources: {cameras: [10.0.0.11, cam-b], xray: 10.0.0.13, offset_y: 400,\n"
      "              exposure_us: 80, packet_size: 8192}\n"
      "  - id: 1\n"
      "    sources: {cameras: [10.0.1.11, 10.0.1.12], xray: 10.0.1.13, trigger: free_run}\n"
      "  - id: 2\n",
      "test");
  const SensorSources& s = p.lane(0).sources;
  ASSERT_TRUE(s.enabled());
  EXPECT_EQ(s.devices(), (std::vector<std::string>{"10.0.0.11", "cam-b", "10.0.0.13"}));
  EXPECT_EQ(s.trigger, LineTrigger::kEncoder);  // the default: a line per encoder pulse
  EXPECT_EQ(s.trigger_line, "Line0");
  EXPECT_EQ(s.offset_y, 400);
  EXPECT_EQ(s.packet_size, 8192);
  EXPECT_EQ(p.lane(1).sources.trigger, LineTrigger::kFreeRun);
  EXPECT_FALSE(p.lane(2).sources.enabled());  // fed over gRPC
  EXPECT_TRUE(p.lane(2).sources.devices().empty());

  auto lanes_error = [](const std::string& lanes) { return error_of("lanes:\n" + lanes); };
  EXPECT_NE(lanes_error("  - {id: 0, sources: {cameras: [a], xray: x}}\n").find("two devices"),
            std::string::npos);
  EXPECT_NE(lanes_error("  - {id: 0, sources: {cameras: [a, b]}}\n").find("missing key 'xray'"),
            std::string::npos);
  EXPECT_NE(lanes_error("  - {id: 0, sources: {cameras: [a, a], xray: x}}\n").find("named twice"),
            std::string::npos);
  EXPECT_NE(lanes_error("  - {id: 0, sources: {cameras: [a, b], xray: x, trigger: pulse}}\n")
                .find("lanes[0].sources.trigger: must be encoder or free_run"),
            std::string::npos);
  EXPECT_NE(lanes_error("  - {id: 0, sources: {cameras: [a, b], xray: x, packet_size: 100}}\n")
                .find("packet_size"),
            std::string::npos);
  EXPECT_NE(lanes_error("  - {id: 0, sources: {cameras: [a, b], xray: x}}\n"
                        "  - {id: 1, sources: {cameras: [c, d], xray: x}}\n")
                .find("device 'x' already belongs to another lane"),
            std::string::npos);
  EXPECT_NE(lanes_error("  - {id: 0, sources: {cameras: [a, b], xray: x, mtu: 9000}}\n")
                .find("unknown key 'mtu'"),
            std::string::npos);
}

TEST(PlantConfig, PlcAndVerificationSectionsAreReadAndChecked) {
  const PlantConfig p = parse_plant_config(
      "plc: {address: 10.0.0.2:502, reject_station_mm: 800, margin_mm: 30}\n"
      "verification: {every_h: 4, fillets: 3, tolerance_mm: 8}\n"
      "lanes: [{id: 0}]\n",
      "test");
  EXPECT_TRUE(p.plc.enabled());
  EXPECT_EQ(p.plc.reject_station_mm, 800);
  EXPECT_EQ(p.plc.ring_base, 200);  // the documented default map
  EXPECT_EQ(p.verification.every_h, 4);
  EXPECT_EQ(p.verification.fillets, 3);
  EXPECT_FALSE(parse_plant_config("lanes: [{id: 0}]\n", "t").plc.enabled());
  // Each section (a one-lane plant's) refused, naming what is wrong.
  const std::pair<const char*, const char*> refused[] = {
      {"plc: {address: plc.local}", "host:port"},
      {"plc: {address: a:1, margin_mm: 2000}",
       "plc.margin_mm: must be >= 0 and less than reject_station_mm"},
      {"plc: {address: a:1, ring_base: 20}", "overlap"},
      // A port that is not one, lane states past the last register (lane 18's would be
      // written to register 0, the heartbeat), times past what a line can wait.
      {"plc: {address: 'a:5o2'}", "plc.address: the port must be a number 1..65535 (got 'a:5o2')"},
      {"plant: {http: '127.0.0.1:80x8'}",
       "plant.http: must be host:port (a port 0..65535; 0: any free one) or off (got "
       "'127.0.0.1:80x8')"},
      {"plant: {http: '127.0.0.1:65536'}", "plant.http: must be host:port"},
      {"plc: {address: 'a:70000'}", "1..65535"},
      {"plc: {address: 'a:0'}", "1..65535"},
      {"plc: {address: a:1, lane_state_base: 65500}",
       "plc.lane_state_base: the lane states (2 x 64 lanes) run past register 65535"},
      {"plc: {address: a:1, timeout_ms: 1e7}", "plc.timeout_ms: must be at most 60000"},
      {"plc: {address: a:1, heartbeat_ms: 1e9}", "plc.heartbeat_ms: must be at most 60000"},
      {"verification: {every_h: -1}", "every_h"},
      {"verification: {fillets: 0}", "fillets"}};
  for (const auto& [section, words] : refused) {
    const std::string why = error_of(std::string(section) + "\nlanes: [{id: 0}]\n");
    EXPECT_NE(why.find(words), std::string::npos) << section << ": " << why;
  }
  EXPECT_NE(error_of("plc: {address: a:1}\nlanes: [{id: 64}]\n").find("lane ids go up to 63"),
            std::string::npos);
}
