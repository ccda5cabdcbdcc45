// Store and forward: everything a rangexd stores (decisions with their fragments, audit
// entries with their chain links, image references, calibration and learned-settings
// versions) goes on to the plant-wide PostgreSQL once it is durable locally. Exactly once:
// each batch is one transaction of writes keyed by the server and its local keys, with the
// cursor that says how far the database holds; after an outage, a cut or a crash it resumes
// from that cursor. Inspection never waits for it. docs/plant-wide.md.
#pragma once
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include "plantdb/forward_status.h"
#include "store/forward_batch.h"

namespace rangex {

class PgConnection;
class Store;

struct ForwarderOptions {
  std::string conninfo;   // plant.results_db
  std::string server_id;  // plant.server_id
  std::string host;       // where this server runs
  int batch_links = 500;
  double idle_s = 0.25;     // how often a caught-up forwarder looks for new records
  double retry_max_s = 30;  // backoff after a failure: 1 s, doubling, up to this
  int connect_timeout_s = 5;
  // A statement longer is cancelled by the server; one with no answer 5 s later (a hung
  // host) fails, and the forwarder connects again with its backoff.
  int statement_timeout_s = 60;
  double heartbeat_s = 5;  // how often a caught-up forwarder says it is alive
};

class Forwarder {
 public:
  Forwarder(Store& store, ForwarderOptions opt);
  ~Forwarder();  // stops
  Forwarder(const Forwarder&) = delete;
  Forwarder& operator=(const Forwarder&) = delete;

  void start();
  void stop();
  ForwarderStatus status() const;
  // Caught up with everything stored when it was called, within timeout_s (tests, a stop).
  bool wait_caught_up(double timeout_s);
  // What the fleet view shows of this server, written to its `servers` row at every
  // heartbeat: where its dashboard serves ("http://host:port": the fleet fetches images
  // there) and its health as JSON text (lanes, warnings), read from `health` each time.
  void describe(const std::string& http_url, std::function<std::string()> health);

 private:
  void run();
  void connect();                         // throws Error
  void forward(const ForwardBatch& b);    // one transaction; throws Error
  void heartbeat(const ForwardBatch& b);  // the servers row's lag and health
  void note_lag(const ForwardBatch& b);
  // The connection in use, replaced under db_mu_ so that stop() can interrupt the one a
  // statement waits on; after stop() each new one is interrupted as it is made.
  void set_db(std::unique_ptr<PgConnection> db);

  Store& store_;
  const ForwarderOptions opt_;
  std::mutex db_mu_;
  std::unique_ptr<PgConnection> db_;
  bool interrupted_ = false;  // under db_mu_
  ForwardCursor cursor_;
  bool need_active_ = true;
  std::set<std::string> days_;  // day partitions known to exist
  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool stop_ = false;
  ForwarderStatus status_;
  std::string http_url_;
  std::function<std::string()> health_;
  std::thread thread_;
};

// This machine's host name (the default plant.server_id).
std::string host_name();

// The UTC day of a time (ns since the epoch), as PostgreSQL reads a date: "2026-11-27".
std::string utc_day(int64_t ns);

}  // namespace rangex
