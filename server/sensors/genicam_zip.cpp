#include "sensors/genicam_zip.h"

#include <algorithm>

#include "core/error.h"
#include "core/utf8.h"

namespace rangex {

namespace {

constexpr uint32_t kEndOfDirectory = 0x06054b50, kDirectoryEntry = 0x02014b50,
                   kLocalHeader = 0x04034b50;
constexpr uint64_t kEndBytes = 22, kEntryBytes = 46, kLocalBytes = 30;

// Little-endian fields; the caller has checked that they lie inside the archive.
uint32_t le16(std::string_view z, uint64_t at) {
  return uint32_t(uint8_t(z[at])) | uint32_t(uint8_t(z[at + 1])) << 8;
}
uint32_t le32(std::string_view z, uint64_t at) {
  return le16(z, at) | le16(z, at + 2) << 16;
}

}  // namespace

bool genicam_is_zip(const std::string& name) {
  return name.size() >= 4 && name.compare(name.size() - 4, 4, ".zip") == 0;
}

std::string genicam_zip_refusal(std::string_view z, uint64_t max_unzipped) {
  const uint64_t size = z.size();
  // Aravis takes the last end-of-directory signature, searching back from the end.
  uint64_t end = 0;
  for (uint64_t i = size >= 4 ? size - 4 : 0; i > 0; --i)
    if (le32(z, i) == kEndOfDirectory) {
      end = i;
      break;
    }
  if (end == 0) return "the archive has no end of its central directory";
  if (end + kEndBytes > size) return "the archive's end of directory is cut short";
  const uint32_t files = le16(z, end + 10);
  if (le16(z, end + 8) != files || files == 0) return "the archive lists no file";
  const uint64_t directory_bytes = le32(z, end + 12), directory_at = le32(z, end + 16);
  if (directory_at + directory_bytes > end)
    return join("the archive's directory (", directory_bytes, " bytes at ", directory_at,
                ") overlaps its end at ", end);
  // Aravis adds the bytes before the archive (a self-extractor's) to every offset.
  const uint64_t before = end - (directory_at + directory_bytes);
  uint64_t at = before + directory_at;
  for (uint32_t f = 0; f < files; ++f) {
    if (at + kEntryBytes > size) return join("the archive's entry ", f + 1, " lies past its end");
    if (le32(z, at) != kDirectoryEntry) {
      if (f == 0) return "the archive's directory holds no entry";
      break;  // Aravis lists the entries before this one
    }
    const uint64_t packed = le32(z, at + 20), unpacked = le32(z, at + 24),
                   local = before + le32(z, at + 42);
    const uint64_t name_bytes = le16(z, at + 28);
    if (at + kEntryBytes + name_bytes > size)
      return join("the archive's entry ", f + 1, " has a name past its end");
    const std::string which =
        join("the archive's file '",
             valid_utf8(z.substr(at + kEntryBytes, std::min<uint64_t>(name_bytes, 80))), "'");
    if (unpacked == 0) return which + " is empty";
    if (unpacked > max_unzipped)
      return join(which, " unzips to ", unpacked, " bytes, more than the ", max_unzipped,
                  " a description may have");
    if (local + kLocalBytes > size || le32(z, local) != kLocalHeader)
      return which + " has no header where the directory says";
    const uint64_t data = local + kLocalBytes + le16(z, local + 26) + le16(z, local + 28);
    // Aravis inflates `packed` bytes when they are fewer than `unpacked`, else copies `unpacked`.
    const uint64_t read = packed < unpacked ? packed : unpacked;
    if (data + read > size)
      return join(which, " has ", read, " bytes at ", data, ", past the archive's end at ", size);
    at += kEntryBytes + name_bytes + le16(z, at + 30) + le16(z, at + 32);
  }
  return "";
}

}  // namespace rangex
