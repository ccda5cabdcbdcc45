// invalid_utf8_at against glibc's iconv, an independent UTF-8 decoder with the same rules
// (RFC 3629: overlong forms, surrogates and code points past U+10FFFF refused).
#include <gtest/gtest.h>
#include <iconv.h>

#include <cerrno>
#include <random>
#include <string>
#include <vector>

#include "core/utf8.h"

using namespace rangex;

namespace {
// Where iconv stops decoding s as UTF-8, or npos when it decodes all of it.
size_t iconv_invalid_at(iconv_t cd, const std::string& s) {
  iconv(cd, nullptr, nullptr, nullptr, nullptr);
  std::string in = s;
  std::vector<char> out(4 * s.size() + 8);
  char* ip = in.data();
  size_t il = in.size();
  char* op = out.data();
  size_t ol = out.size();
  if (iconv(cd, &ip, &il, &op, &ol) != size_t(-1)) return std::string::npos;
  EXPECT_TRUE(errno == EILSEQ || errno == EINVAL) << errno;
  return size_t(ip - in.data());
}
}  // namespace

TEST(Utf8, KnownSequences) {
  EXPECT_EQ(invalid_utf8_at(""), std::string::npos);
  EXPECT_EQ(invalid_utf8_at("plain"), std::string::npos);
  EXPECT_EQ(invalid_utf8_at("\xc3\xa6 \xe2\x82\xac \xf0\x9d\x84\x9e \xf4\x8f\xbf\xbf"),
            std::string::npos);
  EXPECT_EQ(invalid_utf8_at("ab\xff"), 2u);
  EXPECT_EQ(invalid_utf8_at("a\xc0\x80"), 1u);         // overlong NUL
  EXPECT_EQ(invalid_utf8_at("\xe0\x80\x80"), 0u);      // overlong
  EXPECT_EQ(invalid_utf8_at("x\xed\xa0\x80"), 1u);     // a surrogate
  EXPECT_EQ(invalid_utf8_at("\xf4\x90\x80\x80"), 0u);  // past U+10FFFF
  EXPECT_EQ(invalid_utf8_at("\xe2\x82"), 0u);          // cut short
  EXPECT_EQ(invalid_utf8_at("\xc3\xa6\x80"), 2u);      // a lone continuation byte
}

TEST(Utf8, AgreesWithIconvOnRandomBytes) {
  iconv_t cd = iconv_open("UTF-32LE", "UTF-8");
  ASSERT_NE(cd, iconv_t(-1));
  std::mt19937 rng(11);
  // Bytes drawn so that well-formed sequences are common: ASCII, continuation bytes, and
  // every lead byte, the edges of their ranges included.
  const std::vector<unsigned char> pool = {'a',  0x00, 0x7f, 0x80, 0x8f, 0x90, 0x9f, 0xa0, 0xbf,
                                           0xc0, 0xc1, 0xc2, 0xdf, 0xe0, 0xe1, 0xec, 0xed, 0xee,
                                           0xef, 0xf0, 0xf1, 0xf3, 0xf4, 0xf5, 0xff};
  int valid = 0;
  for (int k = 0; k < 200000; ++k) {
    std::string s(1 + rng() % 8, ' ');
    for (char& c : s) c = char(pool[rng() % pool.size()]);
    const size_t ours = invalid_utf8_at(s), theirs = iconv_invalid_at(cd, s);
    ASSERT_EQ(ours, theirs) << "case " << k;
    valid += ours == std::string::npos;
  }
  iconv_close(cd);
  EXPECT_GT(valid, 1000);  // the comparison saw well-formed text too
}

TEST(Utf8, ValidUtf8IsUtf8ByIconvAndLeavesUtf8AsItIs) {
  iconv_t cd = iconv_open("UTF-32LE", "UTF-8");
  ASSERT_NE(cd, iconv_t(-1));
  EXPECT_EQ(valid_utf8("Vend\xe4r #1"), "Vend\xEF\xBF\xBDr #1");
  EXPECT_EQ(valid_utf8("\xc3\xa6 \xe2\x82"), "\xc3\xa6 \xEF\xBF\xBD\xEF\xBF\xBD");
  std::mt19937 rng(12);
  for (int k = 0; k < 20000; ++k) {
    std::string s(1 + rng() % 8, ' ');
    for (char& c : s) c = char(rng() % 2 ? 'a' + rng() % 3 : 0x80 + rng() % 128);
    const std::string v = valid_utf8(s);
    ASSERT_EQ(iconv_invalid_at(cd, v), std::string::npos) << "case " << k;
    if (iconv_invalid_at(cd, s) == std::string::npos) ASSERT_EQ(v, s) << "case " << k;
  }
  iconv_close(cd);
}
