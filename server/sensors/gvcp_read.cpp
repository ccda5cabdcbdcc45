#include "sensors/gvcp_read.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <vector>

#include "core/error.h"
#include "sensors/hex_text.h"

namespace rangex {

namespace {

constexpr uint16_t kGvcpPort = 3956;
constexpr uint8_t kGvcpKey = 0x42, kAckRequired = 0x01;
constexpr uint16_t kReadMemCmd = 0x0084, kReadMemAck = 0x0085;

void put16(uint8_t* p, uint16_t v) {
  p[0] = uint8_t(v >> 8);
  p[1] = uint8_t(v);
}
void put32(uint8_t* p, uint32_t v) {
  put16(p, uint16_t(v >> 16));
  put16(p + 2, uint16_t(v));
}
uint16_t get16(const uint8_t* p) {
  return uint16_t(p[0] << 8 | p[1]);
}

struct Socket {
  int fd = -1;
  ~Socket() {
    if (fd >= 0) close(fd);
  }
};

}  // namespace

std::string gvcp_read_memory(const std::string& ipv4, uint32_t address, uint16_t count,
                             int timeout_ms, int tries) {
  if (count == 0 || count % 4 != 0 || count > kGvcpReadMax)
    fail("GVCP read of ", count, " bytes: 4 to ", kGvcpReadMax, " in steps of 4");
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(kGvcpPort);
  if (inet_pton(AF_INET, ipv4.c_str(), &to.sin_addr) != 1)
    fail("GVCP: '", ipv4, "' is not an IPv4 address");
  Socket s;
  s.fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (s.fd < 0) fail("GVCP: socket: ", std::strerror(errno));
  for (int t = 0; t < tries; ++t) {
    const uint16_t id = uint16_t(1 + t);
    uint8_t cmd[16];
    cmd[0] = kGvcpKey;
    cmd[1] = kAckRequired;
    put16(cmd + 2, kReadMemCmd);
    put16(cmd + 4, 8);
    put16(cmd + 6, id);
    put32(cmd + 8, address);
    put16(cmd + 12, 0);
    put16(cmd + 14, count);
    // Not connected: a device may answer from another port than the one asked.
    if (sendto(s.fd, cmd, sizeof cmd, 0, reinterpret_cast<const sockaddr*>(&to), sizeof to) !=
        ssize_t(sizeof cmd))
      continue;
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                            end - std::chrono::steady_clock::now())
                            .count();
      pollfd p{s.fd, POLLIN, 0};
      if (left <= 0 || poll(&p, 1, int(left)) <= 0) break;
      std::vector<uint8_t> ack(12 + kGvcpReadMax);
      sockaddr_in from{};
      socklen_t from_len = sizeof from;
      const ssize_t n =
          recvfrom(s.fd, ack.data(), ack.size(), 0, reinterpret_cast<sockaddr*>(&from), &from_len);
      if (n < 12 || from.sin_addr.s_addr != to.sin_addr.s_addr ||
          get16(ack.data() + 2) != kReadMemAck || get16(ack.data() + 6) != id)
        continue;  // another host's datagram, or a late answer to an earlier try
      if (const uint16_t status = get16(ack.data()); status != 0)
        fail("GVCP: device ", ipv4, " refuses to read ", count, " bytes at ", hex32(address),
             " (status ", hex32(status), ")");
      if (size_t(n) < 12 + size_t(count))
        fail("GVCP: device ", ipv4, " answered ", n - 12, " of ", count, " bytes at ",
             hex32(address));
      return std::string(reinterpret_cast<const char*>(ack.data()) + 12, count);
    }
  }
  fail("GVCP: device ", ipv4, " did not answer a read of its memory (", tries, " tries of ",
       timeout_ms, " ms)");
}

std::string gvcp_read_range(const std::string& ipv4, uint64_t address, uint64_t size,
                            double limit_s) {
  if (address + size > (uint64_t(1) << 32))
    fail("GVCP: ", size, " bytes at ", address, " run past the device's 32-bit addresses");
  const auto start = std::chrono::steady_clock::now();
  std::string out;
  out.reserve(size);
  for (uint64_t done = 0; done < size;) {
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > limit_s)
      fail("GVCP: device ", ipv4, " took more than ", limit_s, " s to give ", size, " bytes (",
           done, " read)");
    const uint64_t want = std::min<uint64_t>(size - done, kGvcpReadMax);
    const uint16_t count = uint16_t((want + 3) / 4 * 4);  // reads are whole registers
    out += gvcp_read_memory(ipv4, uint32_t(address + done), count).substr(0, want);
    done += want;
  }
  return out;
}

}  // namespace rangex
