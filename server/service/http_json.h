// The JSON the HTTP API answers with: a stored fillet with its fragments, a lane's tile
// (rates from the plant's history and its light), the images a fillet has.
#pragma once
#include <httplib.h>

#include <nlohmann/json.hpp>
#include <string>

#include "service/engine.h"
#include "service/plant_history.h"
#include "store/store.h"

namespace rangex {

nlohmann::json fillet_json(const StoredFillet& f);
// An audit entry: ts_ns, who, what, detail.
nlohmann::json audit_json(const AuditEntry& e);
// What an operator's tile shows of a lane, and its light: grey (never fed), red (stopped:
// fed and silent for more than 5 s, or restarted in the last minute), amber (more than 2 %
// of the last 5 minutes' fillets not inspected, or product drift), green.
nlohmann::json lane_json(const LaneState& l, PlantHistory& h, const std::string& backend);
// The images the store keeps of a fillet (rejects and fillets not inspected have them).
nlohmann::json image_kinds(Store& store, int64_t uid);
void send_json(httplib::Response& res, const nlohmann::json& j);

}  // namespace rangex
