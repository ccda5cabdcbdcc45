// What a store hands its forwarder (plantdb/forwarder.h): the records after the local keys
// already in the plant-wide database, in the order they were stored.
#pragma once
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "store/stored_records.h"

namespace rangex {

// The local keys forwarded so far: the chain's seq, the image log's seq, and the rows of
// the two settings tables (never deleted, so their rowids only grow).
struct ForwardCursor {
  int64_t seq = 0, image_seq = 0, calibration_row = 0, learned_row = 0;
  bool operator==(const ForwardCursor&) const = default;
};

struct ForwardLink {
  int64_t seq = 0;
  std::string kind;  // fillet | audit
  int64_t ref = 0, ts_ns = 0;
  std::string prev, hash;
};

struct ForwardImage {
  int64_t seq = 0, uid = 0, decided_ns = 0;
  std::string kind, path;
};

struct ForwardSetting {
  bool learned = false;  // else a calibration
  int64_t row = 0;
  int lane = 0;
  std::string id, yaml, report;
  int64_t uploaded_ns = 0;
};

struct ActiveSetting {
  bool learned = false;
  int lane = 0;
  std::string id;
};

struct ForwardBatch {
  std::vector<ForwardLink> links;
  std::vector<StoredFillet> fillets;                  // the fillet links' rows
  std::vector<std::pair<int64_t, AuditEntry>> audit;  // the audit links' rows
  std::vector<ForwardImage> images;
  std::vector<ForwardSetting> settings;
  std::vector<ActiveSetting> active;  // every active setting, when asked for
  ForwardCursor next;                 // the cursor once this batch is forwarded
  int64_t head_seq = 0;               // the chain's last link in the store
  int64_t oldest_ns = 0;              // the first link after the cursor's time (0: none)
  int64_t pending = 0;                // links after the cursor, this batch's included
  bool empty() const { return links.empty() && images.empty() && settings.empty(); }
};

}  // namespace rangex
