// The server's durable store: an embedded SQLite database of fillet results, fragments,
// image files, calibration versions and an audit log of every control-plane change. Images
// live as PNG files beside the database; the database holds their paths.
#pragma once
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "store/forward_batch.h"
#include "store/stored_records.h"

struct sqlite3;

namespace rangex {

// A versioned lane setting: a calibration set, or learned inspection settings. Versions are
// immutable; one per lane and kind is active.
struct StoredCalibration {
  int lane = 0;
  std::string id, yaml;
  int64_t uploaded_ns = 0;
  bool active = false;
  std::string report;  // the solvers' (or the learning's) JSON report; empty when none came
};
using StoredSetting = StoredCalibration;
enum class SettingKind { kCalibration, kLearned };

// Fillets decided in [from_ns, to_ns) (to_ns 0: no bound), on `lane` (-1: all), with
// `decision` ("": any), uid > after, oldest first, at most `limit`.
struct FilletQuery {
  int64_t from_ns = 0, to_ns = 0;
  int lane = -1;
  std::string decision;
  int64_t after = 0;
  int limit = 1000;
  bool newest_first = false;  // the latest `limit` matches, newest first (after is ignored)
};

// What verifying a store's hash chain found: ok, or the first link that does not hold and
// why (first_broken_seq 0: a row outside the chain).
struct ChainReport {
  bool ok = true;
  int64_t links = 0;
  // Links up to this one were pruned by retention: the chain is verified from the hash the
  // checkpoint keeps, which the latest retention.prune audit entry (itself chained) names.
  int64_t checkpoint_seq = 0;
  std::string head;  // the last link's hash: a record of it elsewhere anchors the chain
  int64_t first_broken_seq = 0;
  bool damaged = false;  // the database itself failed its check (problem names the table)
  std::string problem;
};

struct ChainLink {
  int64_t seq = 0;
  std::string kind;  // fillet | audit
  int64_t ref = 0;   // the fillet's uid or the audit entry's row
  int64_t ts_ns = 0;
  std::string prev, hash, content;
};

// What one retention pass removed (Store::prune).
struct PruneReport {
  int64_t links = 0, fillets = 0, audit_entries = 0, images = 0;
  bool more = false;  // stopped at max_rows with more to prune: call again
  int64_t checkpoint_seq = 0;
  std::string checkpoint_hash;
};

class DirectoryLock;

class Store {
 public:
  // Opens (creating if needed) <dir>/rangex.sqlite and <dir>/images/, the only writer of
  // them: a store another process has open is refused, naming its pid (directory_lock.h).
  explicit Store(const std::string& dir);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  // Returns the uid. `staged_images`: a folder of the fillet's image files (<kind>.png),
  // moved to image_dir(uid) and registered in the same transaction as the decision: a
  // decision is never stored without its images (a restart in between left one so for
  // good: a restarted rangexd does not decide a stored fillet again). The folder is moved
  // back when the commit fails.
  int64_t add_fillet(const StoredFillet& f, const std::string& staged_images = "");
  // Where a fillet's images are written before add_fillet (emptied first).
  std::string staging_dir(const StoredFillet& f) const;
  void add_image(int64_t uid, const std::string& kind, const std::string& path);
  std::string image_dir(int64_t uid) const;
  std::optional<std::string> image_path(int64_t uid, const std::string& kind);
  std::optional<StoredFillet> fillet(int64_t uid);
  // Decided in [from_ns, to_ns) (to_ns 0: no bound), lane -1 for all, uid > after, oldest first.
  std::vector<StoredFillet> list_fillets(int64_t from_ns, int64_t to_ns, int lane, int64_t after,
                                         int limit);
  std::vector<StoredFillet> list_fillets(const FilletQuery& q);
  int64_t count_fillets();

  void add_calibration(const StoredCalibration& c);       // throws Error if (lane, id) exists
  std::vector<StoredCalibration> calibrations(int lane);  // lane -1: all
  std::optional<StoredCalibration> calibration(int lane, const std::string& id);
  void set_active_calibration(int lane, const std::string& id);
  // The same for either kind of versioned lane setting (calibrations, learned settings).
  void add_setting(SettingKind kind, const StoredSetting& c);
  std::vector<StoredSetting> settings(SettingKind kind, int lane);
  std::optional<StoredSetting> setting(SettingKind kind, int lane, const std::string& id);
  void set_active_setting(SettingKind kind, int lane, const std::string& id);

  void audit(const std::string& who, const std::string& what, const std::string& detail);
  std::vector<std::string> audit_log(int limit);     // "ts who what detail", newest last
  std::vector<AuditEntry> audit_entries(int limit);  // the same, field by field
  // The newest `limit` entries whose action starts with `prefix`, oldest first.
  std::vector<AuditEntry> audit_entries_of(const std::string& prefix, int limit);

  // Checks the hash chain of the store in `dir`, opened read-only (rangexd may be running).
  static ChainReport verify_chain(const std::string& dir);
  // The links stamped in [from_ns, to_ns) (to_ns 0: no bound), oldest first, each with its
  // row's canonical content recomputed from the store: with the first link's `prev`, a
  // reader checks them by hashing alone (an export's chain proof).
  static std::vector<ChainLink> chain_links(const std::string& dir, int64_t from_ns, int64_t to_ns);
  // Each lane's durable count (Engine: every line up to it has its outcome stored), kept so
  // that a restarted server knows which resent lines it already had.
  void save_progress(const std::vector<std::pair<int, int64_t>>& lane_durable);
  std::vector<std::pair<int, int64_t>> progress();
  // The last X-ray count of the lane's latest stored fillet (nullopt: none).
  std::optional<int64_t> last_fillet_end(int lane);
  const std::string& dir() const { return dir_; }
  // Fault injection for tests: the database can grow no further than `pages` (its writes
  // then fail with SQLITE_FULL, as on a full disk).
  void cap_pages_for_tests(int64_t pages);
  // The lane's next fillet number: one past the highest stored (0 for a lane with none).
  int64_t next_lane_fillet(int lane);

  // Retention (store_retention.cpp). Images first: the image files of fillets decided before
  // images_before_ns go (passed, then not inspected, then rejected; the records stay). Then
  // records: the chain's oldest links stamped before records_before_ns, with their fillets,
  // fragments, images and audit entries, as a prefix of the chain (it stops at the first
  // link inside retention, so no record inside retention is ever pruned, a reject's least
  // of all). Where the chain now starts is kept as a checkpoint, and the pass is audited.
  // At most max_rows images and max_rows links per call.
  PruneReport prune(int64_t records_before_ns, int64_t images_before_ns, int max_rows = 5000);

  // Forwarding to the plant-wide database (store_forward.cpp). The records after `after`,
  // at most `limit` links (images and settings as many), with every active setting when
  // `with_active`.
  ForwardBatch forward_batch(const ForwardCursor& after, int limit, bool with_active);
  // The seq of the chain's last link (0: none).
  int64_t head_seq();
  // The chain link's hash at `seq` (nullopt: not in the store, or pruned).
  std::optional<std::string> link_hash(int64_t seq);
  // What the plant-wide database holds, kept here too: while forwarding is on, retention
  // prunes nothing after it (hold_unforwarded).
  void set_forwarded(const ForwardCursor& c);
  ForwardCursor forwarded();
  void hold_unforwarded(bool on) { hold_unforwarded_ = on; }

  std::string chain_head() {
    std::lock_guard<std::mutex> lock(mu_);
    return head_;
  }

 private:
  void exec(const std::string& sql);
  // An image's row and its log entry, in the open transaction (mu_ held).
  void register_image(int64_t uid, const std::string& kind, const std::string& path);
  void rollback() noexcept;  // the open transaction, if SQLite has not rolled it back itself
  Store();  // a view of a read-only connection (verify_chain, chain_links); no lock
  static std::unique_ptr<Store> read_only(const std::string& dir);
  // The tables whose pages or indexes are damaged, with SQLite's first complaint for each
  // ("" when all check out).
  static std::string damage(sqlite3* db);
  std::string row_content(const std::string& kind, int64_t ref);  // throws NotFound
  void add_column(const std::string& table, const std::string& column, const std::string& decl);
  void chain_existing();
  std::string append_link(const char* kind, int64_t ref, int64_t ts_ns, const std::string& content,
                          const std::string& prev);
  ForwardCursor forwarded_locked();       // mu_ held
  int64_t head_seq_locked();              // the chain's last link's seq (0: none); mu_ held
  AuditEntry read_audit(int64_t row);     // throws NotFound; mu_ held
  StoredFillet read_fillet(int64_t uid);  // with its fragments in stored order; mu_ held
  // An audit entry and its link, inside the caller's transaction (mu_ held); the new head.
  std::string append_audit(const AuditEntry& e, const std::string& prev);
  int64_t prune_images(int64_t before_ns, int max_rows, std::vector<std::string>& files);
  std::string dir_;
  std::unique_ptr<DirectoryLock> lock_;  // null in a read-only view
  sqlite3* db_ = nullptr;
  std::mutex mu_;
  std::string head_;  // the chain's last hash
  std::atomic<bool> hold_unforwarded_{false};
};

int64_t now_ns();

}  // namespace rangex
