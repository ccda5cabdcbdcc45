// Bounds on what rangex reads, checked before anything is parsed: a 50 MB YAML
// took rangexd to 7.9 GB and std::bad_alloc, since a YAML tree costs about 150 bytes a byte.
// Each bound is far above what a plant's real documents need (a 16-lane plant.yaml is about
// 10 kB, a calibration 2 kB, learned settings 2 kB, a report 20 kB).
#pragma once
#include <cstddef>
#include <string>

namespace rangex {

constexpr size_t kMaxPlantConfigBytes = size_t(2) << 20;  // plant.yaml
constexpr size_t kMaxCalibrationBytes = size_t(1) << 20;  // one lane's calibration YAML
constexpr size_t kMaxLearnedBytes = size_t(1) << 20;      // one lane's learned settings YAML
constexpr size_t kMaxReportBytes = size_t(4) << 20;       // a calibration's or learning's report
// A lane's last live learning run's fillet images, kept in memory for a re-learning.
constexpr size_t kMaxKeptLearningBytes = size_t(64) << 20;
constexpr size_t kMaxYamlBytes = kMaxPlantConfigBytes;  // any YAML document at all

// An id or a name a client gives (a calibration's, learned settings', a recording's): listed,
// audited and logged, one line each.
constexpr size_t kMaxNameBytes = 100;

// Throws an Error naming `what`, its size and the bound when bytes > limit.
void check_size(const std::string& what, size_t bytes, size_t limit);
// Throws an Error naming `what` unless `name` is 1..max_bytes bytes without control
// characters (a line break in an id would break each line that lists, audits or logs it).
void check_name(const std::string& what, const std::string& name, size_t max_bytes = kMaxNameBytes);

}  // namespace rangex
