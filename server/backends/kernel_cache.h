// Where compiled kernels and pipelines are cached across restarts (OpenCL program binaries,
// the Vulkan pipeline cache): $RANGEX_KERNEL_CACHE, else $XDG_CACHE_HOME/rangex/kernels,
// else ~/.cache/rangex/kernels; empty when none can be named (no cache).
#pragma once
#include <cstdlib>
#include <filesystem>

namespace rangex {

inline std::filesystem::path kernel_cache_dir() {
  namespace fs = std::filesystem;
  if (const char* d = std::getenv("RANGEX_KERNEL_CACHE")) return d;
  if (const char* d = std::getenv("XDG_CACHE_HOME")) return fs::path(d) / "rangex" / "kernels";
  if (const char* d = std::getenv("HOME")) return fs::path(d) / ".cache" / "rangex" / "kernels";
  return {};
}

}  // namespace rangex
