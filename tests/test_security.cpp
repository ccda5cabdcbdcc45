// Identity and roles: rangexd over TLS with client certificates and bearer tokens
// from a test CA made by scripts/make-test-ca.sh. Every RPC is called by every kind of
// caller and must be refused exactly when the caller's role is below the one the RPC needs
// (the table below is the specification, and it must name every method the services
// declare); the audit names the identity the connection proved; certificates of another CA,
// plaintext clients and unknown tokens are refused; and rangexd will not serve beyond
// loopback without TLS unless told it may. The HTTP side is checked with httplib's client.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>

#include "channel.h"
#include "core/plant_config.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "service/access_control.h"
#include "service/http_server.h"
#include "service/server.h"
#include "store/sha256_hex.h"
#include "temp_dir.h"
#include "test_ca.h"

namespace rangex {
namespace {

namespace pb = rangex::v1;
using test::TempDir;
using Code = grpc::StatusCode;

std::string pki(const std::string& file) {
  return test::test_ca(file);
}

const char* kEngineerToken = "rgx_engineer-token-for-tests";
const char* kViewerToken = "rgx_viewer-token-for-tests";

PlantConfig secured_plant() {
  PlantConfig p = default_plant_config(2);
  SecurityConfig& s = p.security;
  s.tls_cert = pki("server.crt");
  s.tls_key = pki("server.key");
  s.client_ca = pki("ca.crt");
  s.identities = {{"viewer-1", Role::viewer},
                  {"operator-1", Role::operator_},
                  {"engineer-1", Role::engineer},
                  {"admin-1", Role::admin}};
  s.tokens = {{"line-engineer", Role::engineer, sha256_hex(kEngineerToken)},
              {"qa-screen", Role::viewer, sha256_hex(kViewerToken)}};
  return p;
}

ServerOptions options(const TempDir& dir) {
  ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.data_dir = dir.str("data");
  o.engine.backend.name = "cpu";
  return o;
}

// A caller: a client certificate's name, a token, or neither.
struct Caller {
  std::string name;
  std::string cert;   // file prefix in the test CA ("" none)
  std::string token;  // "" none
  Role role;          // what the server should grant
  bool anonymous = false;
};

std::shared_ptr<grpc::Channel> channel_for(const RangexServer& s, const Caller& c) {
  ClientSecurity sec;
  sec.ca = pki("ca.crt");
  if (!c.cert.empty()) {
    sec.cert = pki(c.cert + ".crt");
    sec.key = pki(c.cert + ".key");
  }
  sec.token = c.token;
  return rangex_channel(s.address(), sec);
}

std::chrono::system_clock::time_point soon(int ms = 5000) {
  return std::chrono::system_clock::now() + std::chrono::milliseconds(ms);
}

// One call of `method` with a harmless request; its status.
grpc::Status call(const std::shared_ptr<grpc::Channel>& ch, const std::string& method) {
  grpc::ClientContext ctx;
  ctx.set_deadline(soon());
  auto results = pb::ResultsService::NewStub(ch);
  auto cal = pb::CalibrationService::NewStub(ch);
  auto control = pb::ControlService::NewStub(ch);
  if (method == "StreamLines") {
    auto stream = pb::IngestService::NewStub(ch)->StreamLines(&ctx);
    pb::StreamLinesRequest q;
    q.set_credit_query(true);
    stream->Write(q);
    stream->WritesDone();
    pb::StreamLinesResponse r;
    while (stream->Read(&r)) {
    }
    return stream->Finish();
  }
  if (method == "SubscribeFillets") {
    ctx.set_deadline(soon(300));  // allowed: it streams until the deadline
    auto stream = results->SubscribeFillets(&ctx, pb::SubscribeFilletsRequest());
    pb::SubscribeFilletsResponse r;
    while (stream->Read(&r)) {
    }
    return stream->Finish();
  }
  if (method == "GetFillet") {
    pb::GetFilletResponse r;
    return results->GetFillet(&ctx, pb::GetFilletRequest(), &r);
  }
  if (method == "ListFillets") {
    pb::ListFilletsResponse r;
    return results->ListFillets(&ctx, pb::ListFilletsRequest(), &r);
  }
  if (method == "GetFilletImage") {
    pb::GetFilletImageResponse r;
    return results->GetFilletImage(&ctx, pb::GetFilletImageRequest(), &r);
  }
  if (method == "UploadCalibration") {
    pb::UploadCalibrationRequest q;
    q.set_id("probe");
    q.set_yaml("not: [valid");
    pb::UploadCalibrationResponse r;
    return cal->UploadCalibration(&ctx, q, &r);
  }
  if (method == "ListCalibrations") {
    pb::ListCalibrationsResponse r;
    return cal->ListCalibrations(&ctx, pb::ListCalibrationsRequest(), &r);
  }
  if (method == "GetCalibration") {
    pb::GetCalibrationResponse r;
    return cal->GetCalibration(&ctx, pb::GetCalibrationRequest(), &r);
  }
  if (method == "ActivateCalibration") {
    pb::ActivateCalibrationRequest q;
    q.set_id("no-such-set");
    pb::ActivateCalibrationResponse r;
    return cal->ActivateCalibration(&ctx, q, &r);
  }
  if (method == "ListLanes") {
    pb::ListLanesResponse r;
    return control->ListLanes(&ctx, pb::ListLanesRequest(), &r);
  }
  if (method == "UpdateLaneThresholds") {
    pb::UpdateLaneThresholdsResponse r;  // no field set: changes nothing
    return control->UpdateLaneThresholds(&ctx, pb::UpdateLaneThresholdsRequest(), &r);
  }
  if (method == "ResetLane") {
    pb::ResetLaneRequest q;
    q.set_lane(1);
    q.set_reason("role probe");
    pb::ResetLaneResponse r;
    return control->ResetLane(&ctx, q, &r);
  }
  if (method == "GetStatistics") {
    pb::GetStatisticsResponse r;
    return control->GetStatistics(&ctx, pb::GetStatisticsRequest(), &r);
  }
  if (method == "GetServerInfo") {
    pb::GetServerInfoResponse r;
    return control->GetServerInfo(&ctx, pb::GetServerInfoRequest(), &r);
  }
  if (method == "UploadLearnedSettings") {
    pb::UploadLearnedSettingsRequest q;
    q.set_id("probe");
    q.set_yaml("not: [valid");
    pb::UploadLearnedSettingsResponse r;
    return control->UploadLearnedSettings(&ctx, q, &r);
  }
  if (method == "ListLearnedSettings") {
    pb::ListLearnedSettingsRequest q;
    q.set_lane(-1);
    pb::ListLearnedSettingsResponse r;
    return control->ListLearnedSettings(&ctx, q, &r);
  }
  if (method == "ActivateLearnedSettings") {
    pb::ActivateLearnedSettingsRequest q;
    q.set_id("no-such-set");
    pb::ActivateLearnedSettingsResponse r;
    return control->ActivateLearnedSettings(&ctx, q, &r);
  }
  if (method == "LearnProduct") {
    pb::LearnProductRequest q;
    q.set_lane(99);  // no such lane: answered at once, never waiting for fillets
    pb::LearnProductResponse r;
    return control->LearnProduct(&ctx, q, &r);
  }
  if (method == "StartVerification") {
    pb::StartVerificationRequest q;
    q.set_lane(99);  // no such lane: refused at once
    pb::StartVerificationResponse r;
    return control->StartVerification(&ctx, q, &r);
  }
  if (method == "StartRecording") {
    pb::StartRecordingRequest q;  // no minutes: refused at once
    pb::StartRecordingResponse r;
    return control->StartRecording(&ctx, q, &r);
  }
  if (method == "StopRecording") {
    pb::StopRecordingResponse r;  // none running: refused at once
    return control->StopRecording(&ctx, {}, &r);
  }
  ADD_FAILURE() << "the test cannot call " << method;
  return grpc::Status(Code::INTERNAL, "not called");
}

// The role model (docs/security.md): the role each RPC needs.
const std::map<std::string, Role> kNeeded = {
    {"StreamLines", Role::operator_},
    {"SubscribeFillets", Role::viewer},
    {"GetFillet", Role::viewer},
    {"ListFillets", Role::viewer},
    {"GetFilletImage", Role::viewer},
    {"UploadCalibration", Role::engineer},
    {"ListCalibrations", Role::viewer},
    {"GetCalibration", Role::viewer},
    {"ActivateCalibration", Role::engineer},
    {"ListLanes", Role::viewer},
    {"UpdateLaneThresholds", Role::operator_},
    {"ResetLane", Role::operator_},
    {"GetStatistics", Role::viewer},
    {"GetServerInfo", Role::viewer},
    {"UploadLearnedSettings", Role::engineer},
    {"ListLearnedSettings", Role::viewer},
    {"ActivateLearnedSettings", Role::engineer},
    {"LearnProduct", Role::engineer},
    {"StartVerification", Role::operator_},
    {"StartRecording", Role::operator_},
    {"StopRecording", Role::operator_},
};

TEST(Access, TheRoleTableNamesEveryMethodOfEveryService) {
  std::set<std::string> declared;
  const auto* file = pb::StreamLinesRequest::descriptor()->file();  // rangex.proto
  ASSERT_EQ(file->service_count(), 4);
  for (int k = 0; k < file->service_count(); ++k)
    for (int i = 0; i < file->service(k)->method_count(); ++i)
      declared.insert(file->service(k)->method(i)->name());
  std::set<std::string> table;
  for (const auto& [m, r] : kNeeded) table.insert(m);
  EXPECT_EQ(declared, table) << "an RPC was added or removed: give it its role here and in "
                                "the server, and test it";
}

TEST(Access, EveryRpcIsRefusedBelowItsRoleAndAllowedFromIt) {
  TempDir dir;
  RangexServer server(secured_plant(), options(dir));
  const std::vector<Caller> callers = {
      {"anonymous", "", "", Role::none, true},
      {"a certificate the plant gives no role", "stranger-1", "", Role::none},
      {"viewer certificate", "viewer-1", "", Role::viewer},
      {"viewer token", "", kViewerToken, Role::viewer},
      {"operator certificate", "operator-1", "", Role::operator_},
      {"engineer certificate", "engineer-1", "", Role::engineer},
      {"engineer token", "", kEngineerToken, Role::engineer},
      {"admin certificate", "admin-1", "", Role::admin},
  };
  for (const Caller& c : callers) {
    const auto ch = channel_for(server, c);
    for (const auto& [method, needed] : kNeeded) {
      const grpc::Status s = call(ch, method);
      const std::string where = c.name + " calling " + method + ": " + s.error_message();
      if (c.role >= needed) {
        EXPECT_NE(s.error_code(), Code::UNAUTHENTICATED) << where;
        EXPECT_NE(s.error_code(), Code::PERMISSION_DENIED) << where;
        EXPECT_NE(s.error_code(), Code::UNAVAILABLE) << where;
      } else if (c.anonymous) {
        EXPECT_EQ(s.error_code(), Code::UNAUTHENTICATED) << where;
        EXPECT_NE(s.error_message().find("present a client certificate or a bearer token"),
                  std::string::npos)
            << where;
      } else {
        EXPECT_EQ(s.error_code(), Code::PERMISSION_DENIED) << where;
        // The message names the role needed.
        EXPECT_NE(s.error_message().find(std::string("needs the ") + role_name(needed)),
                  std::string::npos)
            << where;
      }
    }
  }
}

// Forcing a calibration past its failed or missing report overrides the server's own check:
// admin only.
TEST(Access, AForcedActivationNeedsAdmin) {
  TempDir dir;
  RangexServer server(secured_plant(), options(dir));
  auto engineer = channel_for(server, {"", "engineer-1", "", Role::engineer});
  auto admin = channel_for(server, {"", "admin-1", "", Role::admin});
  {
    grpc::ClientContext ctx;
    pb::UploadCalibrationRequest up;
    up.set_lane(0);
    up.set_id("hand-written");
    up.set_yaml("laser_plane: {normal: [0, 1, 0], offset_mm: 0.05}\n");
    pb::UploadCalibrationResponse r;
    ASSERT_TRUE(pb::CalibrationService::NewStub(engineer)->UploadCalibration(&ctx, up, &r).ok());
  }
  auto activate = [&](const std::shared_ptr<grpc::Channel>& ch, bool force) {
    grpc::ClientContext ctx;
    pb::ActivateCalibrationRequest q;
    q.set_lane(0);
    q.set_id("hand-written");
    q.set_force(force);
    pb::ActivateCalibrationResponse r;
    return pb::CalibrationService::NewStub(ch)->ActivateCalibration(&ctx, q, &r);
  };
  EXPECT_EQ(activate(engineer, false).error_code(), Code::FAILED_PRECONDITION);  // no report
  const grpc::Status forced = activate(engineer, true);
  EXPECT_EQ(forced.error_code(), Code::PERMISSION_DENIED) << forced.error_message();
  EXPECT_NE(forced.error_message().find("a forced ActivateCalibration needs the admin role"),
            std::string::npos)
      << forced.error_message();
  EXPECT_TRUE(activate(admin, true).ok());
}

// The audit log records who the connection proved to be, never the name a client sends.
TEST(Access, TheAuditRecordsTheProvedIdentityNotTheClaimedOne) {
  TempDir dir;
  RangexServer server(secured_plant(), options(dir));
  auto upload = [&](const Caller& c, const std::string& id) {
    grpc::ClientContext ctx;
    pb::UploadCalibrationRequest up;
    up.set_lane(0);
    up.set_id(id);
    up.set_yaml("laser_plane: {normal: [0, 1, 0], offset_mm: 0.05}\n");
    up.set_who("mallory");  // claimed
    pb::UploadCalibrationResponse r;
    return pb::CalibrationService::NewStub(channel_for(server, c))->UploadCalibration(&ctx, up, &r);
  };
  ASSERT_TRUE(upload({"", "engineer-1", "", Role::engineer}, "by-cert").ok());
  ASSERT_TRUE(upload({"", "", kEngineerToken, Role::engineer}, "by-token").ok());
  {
    grpc::ClientContext ctx;
    pb::UpdateLaneThresholdsRequest q;
    q.set_lane(1);
    q.set_z_threshold(4.5);
    q.set_who("mallory");
    pb::UpdateLaneThresholdsResponse r;
    ASSERT_TRUE(pb::ControlService::NewStub(channel_for(server, {"", "operator-1", "", {}}))
                    ->UpdateLaneThresholds(&ctx, q, &r)
                    .ok());
  }
  bool cert = false, token = false, op = false;
  for (const AuditEntry& e : server.store().audit_entries(100)) {
    EXPECT_EQ(e.who.find("mallory"), std::string::npos) << e.who << " " << e.what;
    cert |= e.who == "cert:engineer-1" && e.what == "calibration.upload" &&
            e.detail.find("by-cert") != std::string::npos;
    token |= e.who == "token:line-engineer" && e.what == "calibration.upload" &&
             e.detail.find("by-token") != std::string::npos;
    op |= e.who == "cert:operator-1" && e.what == "lane.thresholds";
  }
  EXPECT_TRUE(cert);
  EXPECT_TRUE(token);
  EXPECT_TRUE(op);
}

TEST(Access, OtherCasPlaintextAndUnknownTokensAreRefused) {
  TempDir dir;
  PlantConfig plant = secured_plant();
  plant.security.anonymous = Role::viewer;  // even where anonymous callers may read
  RangexServer server(plant, options(dir));
  // A certificate named "admin" from another CA: the handshake fails.
  const grpc::Status rogue = call(channel_for(server, {"", "rogue-admin", "", {}}), "ResetLane");
  EXPECT_EQ(rogue.error_code(), Code::UNAVAILABLE) << rogue.error_message();
  // A plaintext client of a TLS server gets nothing.
  const grpc::Status plain = call(rangex_channel(server.address()), "GetServerInfo");
  EXPECT_EQ(plain.error_code(), Code::UNAVAILABLE) << plain.error_message();
  // A token that matches nothing is refused, not taken as anonymous.
  const grpc::Status bad = call(channel_for(server, {"", "", "rgx_guessed", {}}), "ListLanes");
  EXPECT_EQ(bad.error_code(), Code::UNAUTHENTICATED);
  EXPECT_NE(bad.error_message().find("unknown bearer token"), std::string::npos)
      << bad.error_message();
  // Anonymous reads, as configured, and cannot write.
  const Caller anon{"", "", "", Role::viewer, true};
  EXPECT_TRUE(call(channel_for(server, anon), "ListLanes").ok());
  EXPECT_EQ(call(channel_for(server, anon), "ResetLane").error_code(), Code::UNAUTHENTICATED);
  // The server still serves its own after all of that.
  EXPECT_TRUE(call(channel_for(server, {"", "viewer-1", "", {}}), "GetStatistics").ok());
}

TEST(Access, TokensAndCertificatesAreSentOnlyOverTls) {
  ClientSecurity sec;
  sec.token = kViewerToken;
  EXPECT_THROW(rangex_channel("127.0.0.1:1", sec), Error);
}

// Loopback without TLS is the zero-configuration default; beyond loopback rangexd refuses
// to start plaintext, or with no authentication, unless the configuration says insecure.
TEST(Access, BeyondLoopbackNeedsTlsAndAuthenticationUnlessInsecure) {
  TempDir dir;
  ServerOptions o = options(dir);
  o.listen = "0.0.0.0:0";
  PlantConfig plain = default_plant_config(1);
  try {
    RangexServer s(plain, o);
    ADD_FAILURE() << "served plaintext on 0.0.0.0";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("without TLS"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("security.insecure: true"), std::string::npos);
  }
  PlantConfig tls_only = plain;
  tls_only.security.tls_cert = pki("server.crt");
  tls_only.security.tls_key = pki("server.key");
  try {
    RangexServer s(tls_only, o);
    ADD_FAILURE() << "served on 0.0.0.0 with every client admin";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no authentication"), std::string::npos) << e.what();
  }
  PlantConfig insecure = plain;
  insecure.security.insecure = true;
  RangexServer s(insecure, o);
  EXPECT_GT(s.port(), 0);
  s.shutdown();

  HttpOptions ho;
  ho.listen = "0.0.0.0:0";
  EXPECT_THROW(HttpServer(s.engine(), s.store(), s.hub(), ho), Error);
  ho.security = secured_plant().security;
  HttpServer web(s.engine(), s.store(), s.hub(), ho);  // TLS and authentication: serves
  EXPECT_GT(web.port(), 0);
}

TEST(Access, LoopbackAddressesAreRecognised) {
  for (const char* a : {"127.0.0.1:50051", "localhost:80", "[::1]:50051", "127.1.2.3:0"})
    EXPECT_TRUE(is_loopback_host(a)) << a;
  for (const char* a : {"0.0.0.0:50051", "[::]:50051", "10.0.0.7:50051", "plant-host:50051"})
    EXPECT_FALSE(is_loopback_host(a)) << a;
}

// rangexd with its dashboard, both secured as secured_plant() says.
struct SecuredDashboard {
  TempDir dir;
  RangexServer server{secured_plant(), options(dir)};
  HttpServer web{server.engine(), server.store(), server.hub(), [] {
                   HttpOptions ho;
                   ho.listen = "127.0.0.1:0";
                   ho.security = secured_plant().security;
                   return ho;
                 }()};
};

TEST(Access, TheDashboardOverTlsNeedsAViewer) {
  SecuredDashboard d;
  RangexServer& server = d.server;
  HttpServer& web = d.web;
  auto client = [&](const std::string& cert) {
    auto c = cert.empty() ? std::make_unique<httplib::SSLClient>("127.0.0.1", web.port())
                          : std::make_unique<httplib::SSLClient>(
                                "127.0.0.1", web.port(), pki(cert + ".crt"), pki(cert + ".key"));
    c->set_ca_cert_path(pki("ca.crt").c_str());
    c->enable_server_certificate_verification(true);
    c->set_connection_timeout(5);
    c->set_read_timeout(5);
    return c;
  };
  {
    const auto r = client("")->Get("/api/info");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 401);
    EXPECT_EQ(r->get_header_value("WWW-Authenticate").rfind("Basic", 0), 0u);
  }
  {
    const auto r =
        client("")->Get("/api/info", {{"Authorization", std::string("Bearer ") + kViewerToken}});
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << r->body;
  }
  {
    auto c = client("");
    c->set_basic_auth("anyone", kViewerToken);  // what a browser sends after its prompt
    const auto r = c->Get("/metrics");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
  }
  {
    const auto r = client("viewer-1")->Get("/api/lanes");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << r->body;
  }
  {
    const auto r = client("stranger-1")->Get("/api/lanes");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 403);
    EXPECT_NE(r->body.find("cert:stranger-1 has no role"), std::string::npos) << r->body;
  }
  {
    const auto r = client("")->Get("/", {{"Authorization", "Bearer rgx_guessed"}});
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 401);
  }
  // A client that does not trust the server's CA does not connect.
  httplib::SSLClient untrusting("127.0.0.1", web.port());
  untrusting.set_ca_cert_path(pki("rogue-ca.crt").c_str());
  untrusting.enable_server_certificate_verification(true);
  untrusting.set_connection_timeout(5);
  EXPECT_FALSE(untrusting.Get("/api/info"));
  web.stop();
}

// The dashboard starts a verification run for an operator, from its own origin, with JSON;
// a viewer, another site's page, a form post and a bad body are refused, each saying why.
TEST(Access, TheDashboardStartsAVerificationForAnOperatorOnly) {
  SecuredDashboard d;
  RangexServer& server = d.server;
  HttpServer& web = d.web;
  auto post = [&](const std::string& cert, const std::string& body,
                  const httplib::Headers& headers = {},
                  const std::string& type = "application/json", int lane = 1) {
    httplib::SSLClient c("127.0.0.1", web.port(), pki(cert + ".crt"), pki(cert + ".key"));
    c.set_ca_cert_path(pki("ca.crt").c_str());
    c.enable_server_certificate_verification(true);
    c.set_connection_timeout(5);
    c.set_read_timeout(5);
    auto r = c.Post(("/api/lanes/" + std::to_string(lane) + "/verification").c_str(), headers, body,
                    type.c_str());
    EXPECT_TRUE(r);
    return r ? std::make_pair(r->status, r->body) : std::make_pair(0, std::string());
  };
  const std::string ok = R"({"piece": "2 mm calcified sphere", "x_mm": 40, "fillets": 3})";
  auto [st, body] = post("viewer-1", ok);
  EXPECT_EQ(st, 403);
  EXPECT_NE(body.find("needs the operator role"), std::string::npos) << body;
  std::tie(st, body) = post("operator-1", ok, {}, "application/x-www-form-urlencoded");
  EXPECT_EQ(st, 415) << body;
  std::tie(st, body) = post("operator-1", ok, {{"Origin", "https://evil.example"}});
  EXPECT_EQ(st, 403);
  EXPECT_NE(body.find("origin 'https://evil.example' is refused"), std::string::npos) << body;
  std::tie(st, body) = post("operator-1", ok, {{"Sec-Fetch-Site", "cross-site"}});
  EXPECT_EQ(st, 403) << body;
  std::tie(st, body) = post("operator-1", R"({"piece": "sphere"})");
  EXPECT_EQ(st, 400);
  EXPECT_NE(body.find("x_mm is required"), std::string::npos) << body;
  std::tie(st, body) = post("operator-1", R"({"piece": "sphere", "x_mm": 1, "size": 2})");
  EXPECT_EQ(st, 400);
  EXPECT_NE(body.find("unknown field 'size'"), std::string::npos) << body;
  std::tie(st, body) = post("operator-1", "not json");
  EXPECT_EQ(st, 400) << body;
  std::tie(st, body) = post("operator-1", ok, {}, "application/json", 9);
  EXPECT_EQ(st, 404) << body;
  EXPECT_FALSE(server.engine().lane_state(1).verification.running);

  // From its own origin, as the dashboard's page sends it.
  std::tie(st, body) =
      post("operator-1", ok, {{"Origin", "https://127.0.0.1:" + std::to_string(web.port())}});
  ASSERT_EQ(st, 200) << body;
  EXPECT_NE(body.find("\"running\":true"), std::string::npos) << body;
  const LaneState l = server.engine().lane_state(1);
  EXPECT_TRUE(l.verification.running);
  EXPECT_EQ(l.verification.running_piece, "2 mm calcified sphere");
  EXPECT_EQ(l.verification.fillets_left, 3);
  std::tie(st, body) = post("operator-1", ok);
  EXPECT_EQ(st, 409);  // one at a time on a lane
  EXPECT_NE(body.find("is verifying"), std::string::npos) << body;
  bool audited = false;
  for (const AuditEntry& e : server.store().audit_entries_of("verification.", 10))
    audited |= e.what == "verification.start" && e.who == "cert:operator-1";
  EXPECT_TRUE(audited);
  web.stop();
}

TEST(Access, IdentifyReadsBearerAndBasicAndNeverFallsBack) {
  SecurityConfig s;
  s.tls_cert = "x";
  s.tokens = {{"qa", Role::viewer, sha256_hex("t0k")}};
  s.anonymous = Role::viewer;
  const AccessControl ac(s);
  EXPECT_EQ(ac.identify("", "Bearer t0k", "p").name, "token:qa");
  EXPECT_EQ(ac.identify("", "basic " + std::string("dXNlcjp0MGs="), "p").name,  // user:t0k
            "token:qa");
  EXPECT_THROW(ac.identify("", "Bearer t0", "p"), Unauthenticated);
  EXPECT_THROW(ac.identify("", "Digest abc", "p"), Unauthenticated);
  EXPECT_THROW(ac.identify("", "Basic !!!", "p"), Unauthenticated);
  const Identity anon = ac.identify("", "", "ipv4:10.0.0.9:5000");
  EXPECT_EQ(anon.name, "anonymous@ipv4:10.0.0.9:5000");
  EXPECT_EQ(anon.role, Role::viewer);
  EXPECT_EQ(ac.identify("someone", "", "p").role, Role::none);  // a CN with no role
}

}  // namespace
}  // namespace rangex
