// Learned settings on rangexd: LearnProduct on a live lane fed clean product
// stores a version with its report and sensitivity (and what another false-reject target
// would buy, when asked); activation shows on the lane; a version
// whose report failed is refused unless forced (audited); a restart keeps the active one.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "core/plant_config.h"
#include "feeder.h"
#include "line_source.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "server_client.h"
#include "service/server.h"
#include "sim/plant_simulator.h"
#include "temp_dir.h"

using namespace rangex;
using namespace rangex::test;
namespace pb = rangex::v1;

namespace {

ServerOptions options(const test::TempDir& t) {
  ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.data_dir = t.str("data");
  o.engine.backend = cpu_request(2);
  return o;
}

pb::LaneInfo lane0(pb::ControlService::Stub& control) {
  grpc::ClientContext c;
  pb::ListLanesResponse r;
  EXPECT_TRUE(control.ListLanes(&c, pb::ListLanesRequest(), &r).ok());
  for (const auto& l : r.lanes())
    if (l.id() == 0) return l;
  ADD_FAILURE() << "no lane 0";
  return {};
}

grpc::Status activate(pb::ControlService::Stub& control, const std::string& id, bool force) {
  grpc::ClientContext c;
  pb::ActivateLearnedSettingsRequest q;
  q.set_lane(0);
  q.set_id(id);
  q.set_force(force);
  pb::ActivateLearnedSettingsResponse r;
  return control.ActivateLearnedSettings(&c, q, &r);
}

}  // namespace

TEST(ServerLearning, LearnsALiveLaneAndGatesActivationByItsReport) {
  test::TempDir t;
  const PlantConfig p = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  std::string learned_yaml;
  {
    RangexServer server(p, options(t));
    auto ch = connect(server);
    auto control = pb::ControlService::NewStub(ch);
    // An unknown lane, a bad count: answered at once.
    {
      grpc::ClientContext c;
      pb::LearnProductRequest q;
      q.set_lane(0);
      q.set_fillets(-3);
      pb::LearnProductResponse r;
      EXPECT_EQ(control->LearnProduct(&c, q, &r).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    }
    {
      grpc::ClientContext c;
      pb::LearnProductRequest q;
      q.set_lane(0);
      q.add_tradeoff_targets(0.7);
      pb::LearnProductResponse r;
      const grpc::Status st = control->LearnProduct(&c, q, &r);
      EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
      EXPECT_NE(st.error_message().find("tradeoff_targets"), std::string::npos)
          << st.error_message();
    }
    // LearnProduct waits for the lane's next 30 inspected fillets (the fewest a learning
    // takes by default: with 12, one clean fillet stood out enough to be named once the
    // model took the pixel count through max-stability).
    pb::LearnProductResponse learned;
    grpc::Status status;
    std::thread learner([&] {
      grpc::ClientContext c;
      c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(600));
      pb::LearnProductRequest q;
      q.set_lane(0);
      q.set_fillets(30);
      q.set_id("live-1");
      q.add_tradeoff_targets(0.03);  // what a budget ten times larger would buy
      status = control->LearnProduct(&c, q, &learned);
    });
    std::this_thread::sleep_for(std::chrono::seconds(1));  // the run is registered first
    sim::SimulationParams sp;
    sp.lanes = 1;
    sp.scene.fillets = 33;
    sp.seed = 41;
    sp.physics.bones.probability = 0;  // clean product
    SimulatedSource source(p, sp);
    FeedOptions fo;
    const FeedReport fed = Feeder(ch, fo).run(source);
    EXPECT_TRUE(fed.status.ok()) << fed.status.error_message();
    learner.join();
    ASSERT_TRUE(status.ok()) << status.error_message();
    const pb::LearnedSettingsInfo& s = learned.settings();
    EXPECT_EQ(s.id(), "live-1");
    EXPECT_EQ(s.report_status(), "passed");
    EXPECT_EQ(s.fillets(), 30);
    EXPECT_FALSE(s.active());
    EXPECT_FALSE(s.sensitivity().empty());
    // Stored, not active: the lane still runs its fixed thresholds.
    EXPECT_EQ(lane0(*control).learned_version(), "");
    {
      grpc::ClientContext c;
      pb::ListLearnedSettingsRequest q;
      q.set_lane(0);
      q.set_full(true);
      pb::ListLearnedSettingsResponse r;
      ASSERT_TRUE(control->ListLearnedSettings(&c, q, &r).ok());
      ASSERT_EQ(r.settings_size(), 1);
      learned_yaml = r.settings(0).yaml();
      EXPECT_NE(r.settings(0).report_json().find("\"sensitivity\""), std::string::npos);
      // The other target's thresholds and sensitivity beside the learned one's.
      EXPECT_NE(r.settings(0).report_json().find("\"tradeoff\":[{"), std::string::npos);
      EXPECT_NE(r.settings(0).report_json().find("\"target_frr\":0.03"), std::string::npos);
    }
    ASSERT_TRUE(activate(*control, "live-1", false).ok());
    const pb::LaneInfo l = lane0(*control);
    EXPECT_EQ(l.learned_version(), "live-1");
    EXPECT_FALSE(l.learned_sensitivity().empty());
    EXPECT_DOUBLE_EQ(l.false_reject_target(), 0.003);
    // Under it the lane shows no drift estimate before 200 passed fillets: a rate refitted
    // from fewer is not one the monitor would stand by (it showed one from the 10th before).
    {
      auto passed = [&] {
        const LaneState s = server.engine().lane_state(0);
        return int64_t(s.fillets) - int64_t(s.rejects) - int64_t(s.not_inspected);
      };
      const int64_t before = passed();
      sp.scene.fillets = 16;
      sp.seed = 42;
      SimulatedSource more(p, sp);
      const FeedReport again = Feeder(ch, fo).run(more);
      ASSERT_TRUE(again.status.ok()) << again.status.error_message();
      ASSERT_GE(passed() - before, 10);  // enough for the refit that used to show
      const LaneState s = server.engine().lane_state(0);
      EXPECT_EQ(s.implied_frr, -1);
      EXPECT_EQ(s.drift_fillets, 0);
      EXPECT_FALSE(s.product_drift);
      EXPECT_EQ(lane0(*control).implied_false_reject_rate(), -1);
    }

    // A version whose learning failed: refused, then forced (admin on loopback), audited.
    {
      grpc::ClientContext c;
      pb::UploadLearnedSettingsRequest q;
      q.set_lane(0);
      q.set_id("too-few");
      q.set_yaml(learned_yaml);
      q.set_report_json(
          R"({"lanes": [{"lane": 0, "ok": false, "problems": ["too few clean fillets: 5 of the 30 needed"]}]})");
      pb::UploadLearnedSettingsResponse r;
      ASSERT_TRUE(control->UploadLearnedSettings(&c, q, &r).ok());
      EXPECT_NE(r.settings().report_status().find("too few clean fillets"), std::string::npos);
    }
    const grpc::Status refused = activate(*control, "too-few", false);
    EXPECT_EQ(refused.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    EXPECT_NE(refused.error_message().find("too few clean fillets"), std::string::npos)
        << refused.error_message();
    EXPECT_EQ(activate(*control, "no-such", false).error_code(), grpc::StatusCode::NOT_FOUND);
    {
      grpc::ClientContext c;
      pb::UploadLearnedSettingsRequest q;
      q.set_lane(0);
      q.set_id("garbled");
      q.set_yaml("band_edges_mm: [0, 5]\nround: {thresholds: [nan]}\n");
      pb::UploadLearnedSettingsResponse r;
      const grpc::Status bad = control->UploadLearnedSettings(&c, q, &r);
      EXPECT_EQ(bad.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad.error_message();
    }
    EXPECT_TRUE(activate(*control, "too-few", true).ok());
    EXPECT_EQ(lane0(*control).learned_version(), "too-few");
    bool forced = false, learnt = false;
    for (const std::string& e : server.store().audit_log(100)) {
      forced = forced || e.find("learned.activate.forced") != std::string::npos;
      learnt = learnt || e.find("learned.learn lane 0 id live-1") != std::string::npos;
    }
    EXPECT_TRUE(forced);
    EXPECT_TRUE(learnt);
  }
  // A restart keeps the active version.
  RangexServer again(p, options(t));
  auto control = pb::ControlService::NewStub(connect(again));
  EXPECT_EQ(lane0(*control).learned_version(), "too-few");
}

namespace {

grpc::Status learn(pb::ControlService::Stub& control, const pb::LearnProductRequest& q,
                   pb::LearnProductResponse* r) {
  grpc::ClientContext c;
  c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(600));
  return control.LearnProduct(&c, q, r);
}

}  // namespace

// A live run with bone fails naming the fillets; an operator who checked them and found them
// clean learns again from the same fillets, kept in, without waiting for new product.
TEST(ServerLearning, LearnsAgainFromTheSameFilletsKeepingThoseCheckedClean) {
  test::TempDir t;
  const PlantConfig p = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  RangexServer server(p, options(t));
  auto ch = connect(server);
  auto control = pb::ControlService::NewStub(ch);
  {
    // Nothing learned live yet: nothing to learn again from, and keep needs a run.
    pb::LearnProductRequest q;
    q.set_lane(0);
    q.set_relearn_from("live-bony");
    pb::LearnProductResponse r;
    const grpc::Status st = learn(*control, q, &r);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << st.error_message();
    EXPECT_NE(st.error_message().find("keeps no live learning run"), std::string::npos)
        << st.error_message();
    q.clear_relearn_from();
    q.add_keep_fillets(3);
    const grpc::Status keep = learn(*control, q, &r);
    EXPECT_EQ(keep.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(keep.error_message().find("relearn_from"), std::string::npos) << keep.error_message();
  }
  pb::LearnProductResponse bony;
  grpc::Status status;
  std::thread learner([&] {
    pb::LearnProductRequest q;
    q.set_lane(0);
    q.set_fillets(12);
    q.set_min_fillets(10);
    q.set_id("live-bony");
    q.set_target_frr(0.01);  // learning again keeps it
    status = learn(*control, q, &bony);
  });
  std::this_thread::sleep_for(std::chrono::seconds(1));
  sim::SimulationParams sp;
  sp.lanes = 1;
  sp.scene.fillets = 14;
  sp.seed = 32;  // about half the fillets hold bone
  SimulatedSource source(p, sp);
  const FeedReport fed = Feeder(ch, FeedOptions{}).run(source);
  EXPECT_TRUE(fed.status.ok()) << fed.status.error_message();
  learner.join();
  ASSERT_TRUE(status.ok()) << status.error_message();
  const pb::LearnedSettingsInfo& failed = bony.settings();
  EXPECT_NE(failed.report_status().find("holds something like bone"), std::string::npos)
      << failed.report_status();
  ASSERT_GT(failed.flagged_fillets_size(), 0);
  EXPECT_EQ(activate(*control, "live-bony", false).error_code(),
            grpc::StatusCode::FAILED_PRECONDITION);

  // A fillet the run does not hold, or another run's id: refused, naming what is wrong.
  {
    pb::LearnProductRequest q;
    q.set_lane(0);
    q.set_relearn_from("live-bony");
    q.add_keep_fillets(999999);
    pb::LearnProductResponse r;
    const grpc::Status st = learn(*control, q, &r);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("holds no fillet 999999"), std::string::npos)
        << st.error_message();
    q.set_relearn_from("live-other");
    q.clear_keep_fillets();
    const grpc::Status other = learn(*control, q, &r);
    EXPECT_EQ(other.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    EXPECT_NE(other.error_message().find("those of 'live-bony'"), std::string::npos)
        << other.error_message();
  }
  // Again from the same fillets, the named ones kept: it holds, and says which it kept.
  pb::LearnProductRequest q;
  q.set_lane(0);
  q.set_min_fillets(10);
  q.set_id("live-kept");
  q.set_relearn_from("live-bony");
  for (int64_t f : failed.flagged_fillets()) q.add_keep_fillets(f);
  pb::LearnProductResponse kept;
  const grpc::Status st = learn(*control, q, &kept);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(kept.settings().id(), "live-kept");
  EXPECT_EQ(kept.settings().report_status(), "passed");
  EXPECT_EQ(kept.settings().flagged_fillets_size(), 0);
  EXPECT_EQ(kept.settings().kept_fillets_size(), failed.flagged_fillets_size());
  EXPECT_EQ(kept.settings().fillets(), 12);  // the run's fillets, the kept ones among them
  EXPECT_DOUBLE_EQ(kept.settings().false_reject_target(), 0.01);  // and the run's target
  EXPECT_TRUE(activate(*control, "live-kept", false).ok());
  EXPECT_EQ(lane0(*control).learned_version(), "live-kept");
  // A version learned again from the run names it too, and the run's minimum holds.
  q.set_id("live-kept-2");
  q.set_relearn_from("live-kept");
  q.clear_min_fillets();
  ASSERT_TRUE(learn(*control, q, &kept).ok());
  EXPECT_EQ(kept.settings().report_status(), "passed");
  bool audited = false;
  for (const std::string& e : server.store().audit_log(100))
    audited = audited || (e.find("learned.learn lane 0 id live-kept from 12 fillets of "
                                 "live-bony, kept") != std::string::npos);
  EXPECT_TRUE(audited);
}
