// Between the engine's and store's types and rangex.v1 messages.
#pragma once
#include <string>

#include "rangex/v1/message_json.h"
#include "rangex/v1/rangex.pb.h"
#include "service/engine.h"
#include "store/store.h"

namespace rangex {

void fill(v1::FilletResult* o, const StoredFillet& f);
void fill(v1::CalibrationInfo* o, const StoredCalibration& c, bool with_yaml);
void fill(v1::LearnedSettingsInfo* o, const StoredSetting& s, bool full);
void fill(v1::LaneInfo* o, const LaneState& l);
void fill(v1::RecordingStatus* o, const RecordingStatus& r);
void fill(v1::GetStatisticsResponse* o, const EngineStats& s);

}  // namespace rangex
