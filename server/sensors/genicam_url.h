// What a GigE Vision device names as its GenICam description, in its first URL register
// (0x200): "Local:NAME;ADDRESS;SIZE" in its own memory, "File:PATH" on this host, or another
// scheme, which Aravis 0.8.26 hands to GIO. Aravis reads what is named whole, whatever its
// size: a device naming File:/dev/zero, or a file of 1 GB, took the process opening it to
// 2.07 GB for 10.7 s, and a lane retries a device that fails. So the URL is read and checked
// before Aravis is given the device (gige_device.cpp).
#pragma once
#include <cstdint>
#include <string>

namespace rangex {

struct GenicamUrl {
  std::string scheme;              // lower case: "local", "file", or what the device wrote
  std::string path;                // Local: the file's name; File: its path
  uint64_t address = 0, size = 0;  // Local: where in the device's memory, how many bytes
};

// The register as the device holds it (up to its first NUL). Throws Error naming the text when
// it is not a URL, or a Local: one lacks its address or size in hexadecimal.
GenicamUrl parse_genicam_url(const std::string& text);

// A description larger than this is refused: they are tens to hundreds of kB (zipped less).
constexpr uint64_t kMaxGenicamBytes = uint64_t(16) << 20;

// Why rangex will not have Aravis load it, or "" when it may: a Local: description of 1 to
// max_bytes bytes, or a File: that is a regular file of at most max_bytes bytes. Any other
// scheme is refused (the device would have this host open what it names).
std::string genicam_url_refusal(const GenicamUrl& url, uint64_t max_bytes = kMaxGenicamBytes);

}  // namespace rangex
