// A GenICam description a device names "….zip" is unzipped by Aravis 0.8.26 (arvzip.c) on
// the offsets and sizes the archive declares, none checked against the archive's length: an
// entry whose data lies past the end is read past the end of the buffer (the process crashes),
// and the declared size, up to 4 GiB, is allocated and inflated into (a zip bomb of 16 MiB
// holds 4 GiB). So an archive is walked here the way Aravis walks it, with every read
// bounded, before Aravis is given the device (gige_device.cpp).
#pragma once
#include <cstdint>
#include <string>
#include <string_view>

namespace rangex {

// An unzipped description larger than this is refused: they are tens of kB to a few MB.
constexpr uint64_t kMaxGenicamUnzippedBytes = uint64_t(64) << 20;

// Whether Aravis unzips a description of this name (it looks at the suffix only).
bool genicam_is_zip(const std::string& name);

// Why Aravis must not be given this archive, or "" when it may: every central directory
// entry Aravis lists, its local header and its data lie inside `zip`, and what it unzips to
// is 1 to `max_unzipped` bytes.
std::string genicam_zip_refusal(std::string_view zip,
                                uint64_t max_unzipped = kMaxGenicamUnzippedBytes);

}  // namespace rangex
