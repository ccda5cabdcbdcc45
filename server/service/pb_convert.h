// Between the engine's and store's types and rangex.v1 messages.
#pragma once
#include <string>

#include "rangex/v1/rangex.pb.h"
#include "service/engine.h"
#include "service/store.h"

namespace rangex {

void fill(v1::FilletResult* o, const StoredFillet& f);
void fill(v1::CalibrationInfo* o, const StoredCalibration& c, bool with_yaml);
void fill(v1::LearnedSettingsInfo* o, const StoredSetting& s, bool full);
void fill(v1::LaneInfo* o, const LaneState& l);
void fill(v1::GetStatisticsResponse* o, const EngineStats& s);
// A message in protobuf's JSON mapping, with the .proto's field names and every field
// (zeros included): what `rangexctl status --json` and the HTTP API print.
std::string to_json(const google::protobuf::Message& m);

}  // namespace rangex
