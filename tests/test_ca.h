// The test certificate authority (scripts/make-test-ca.sh), made once per process: its files
// by name ("ca.crt", "server.crt", "viewer-1.key", "rogue-ca.crt", ...). Needs
// RANGEX_SOURCE_DIR (the test's compile definition).
#pragma once
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "temp_dir.h"

namespace rangex::test {

inline std::string test_ca(const std::string& file) {
  static const TempDir dir;
  static const bool made = [] {
    const std::string cmd =
        std::string(RANGEX_SOURCE_DIR) + "/scripts/make-test-ca.sh '" + dir.str() + "' > /dev/null";
    return std::system(cmd.c_str()) == 0;
  }();
  EXPECT_TRUE(made) << "scripts/make-test-ca.sh failed";
  return dir.str(file);
}

}  // namespace rangex::test
