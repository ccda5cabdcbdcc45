// What a GigE Vision device names as its GenICam description, read before Aravis loads it:
// its own memory (Local:) or a regular file of this host (File:), of at most 16 MiB.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "core/error.h"
#include "sensors/genicam_url.h"
#include "temp_dir.h"

using namespace rangex;

TEST(GenicamUrl, LocalAndFileUrlsAreReadAsDevicesWriteThem) {
  GenicamUrl u = parse_genicam_url("Local:arv-fake-camera.xml;10000;3b00");
  EXPECT_EQ(u.scheme, "local");
  EXPECT_EQ(u.path, "arv-fake-camera.xml");
  EXPECT_EQ(u.address, 0x10000u);
  EXPECT_EQ(u.size, 0x3b00u);
  u = parse_genicam_url("local:///Basler_acA2040.zip;8000;1F3A2?SchemaVersion=1.1.0");
  EXPECT_EQ(u.path, "Basler_acA2040.zip");
  EXPECT_EQ(u.address, 0x8000u);
  EXPECT_EQ(u.size, 0x1f3a2u);
  EXPECT_EQ(genicam_url_refusal(u), "");
  u = parse_genicam_url("File:///opt/camera/desc.xml?SchemaVersion=1.0.0");
  EXPECT_EQ(u.scheme, "file");
  EXPECT_EQ(u.path, "/opt/camera/desc.xml");
}

TEST(GenicamUrl, AUrlThatIsNoneIsRefusedNamingIt) {
  for (const char* text : {"", "arv-fake-camera.xml", "Local:x.xml;10000", "Local:x.xml;zz;100",
                           "Local:x.xml;10000;-4", "Local:;10000;100", "Local:x;1;2;3"}) {
    SCOPED_TRACE(text);
    try {
      parse_genicam_url(text);
      ADD_FAILURE() << "taken";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("'") + text + "'"), std::string::npos)
          << e.what();
    }
  }
}

TEST(GenicamUrl, WhatWouldHaveAravisReadTooMuchOrElsewhereIsRefused) {
  test::TempDir t;
  std::ofstream(t.str("desc.xml")) << std::string(1000, 'x');
  const std::string file = "File:" + t.str("desc.xml");
  EXPECT_EQ(genicam_url_refusal(parse_genicam_url(file)), "");
  EXPECT_NE(genicam_url_refusal(parse_genicam_url(file), 999).find("file of 1000 bytes"),
            std::string::npos);
  EXPECT_NE(genicam_url_refusal(parse_genicam_url("File:/dev/zero")).find("not a file"),
            std::string::npos);
  EXPECT_NE(genicam_url_refusal(parse_genicam_url("File:" + t.str("none.xml"))).find("cannot"),
            std::string::npos);
  EXPECT_NE(genicam_url_refusal(parse_genicam_url("Local:x.xml;10000;ffffff00"))
                .find("declares 4294967040 bytes, more than the 16777216"),
            std::string::npos);
  EXPECT_EQ(genicam_url_refusal(parse_genicam_url("Local:x.xml;10000;1000000")), "");  // 16 MiB
  EXPECT_NE(genicam_url_refusal(parse_genicam_url("Local:x.xml;10000;0")).find("empty"),
            std::string::npos);
  for (const char* other : {"http://192.168.1.1/desc.xml", "smb://host/share/desc.xml"})
    EXPECT_NE(genicam_url_refusal(parse_genicam_url(other)).find("Local:"), std::string::npos)
        << other;
}
