#include "plc/plc_simulator.h"

#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <string>

namespace rangex {

namespace {

int free_port() {
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t n = sizeof a;
  getsockname(s, reinterpret_cast<sockaddr*>(&a), &n);
  close(s);
  return ntohs(a.sin_port);
}

}  // namespace

SimPlc::SimPlc(const PlcConfig& cfg, int port)
    : cfg_(cfg),
      port_(port > 0 ? port : free_port()),
      regs_(65536, 0),
      seen_(size_t(cfg.ring_slots), 0) {
  start();
}

SimPlc::~SimPlc() {
  stop();
}

void SimPlc::start() {
  stop_ = false;
  thread_ = std::thread([this] { serve(); });
  while (!serving_) std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

void SimPlc::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  std::lock_guard<std::mutex> lk(mu_);
  std::fill(regs_.begin(), regs_.end(), 0);  // a restarted PLC starts with nothing
  std::fill(seen_.begin(), seen_.end(), 0);
}

void SimPlc::serve() {
  modbus_t* ctx = modbus_new_tcp("127.0.0.1", port_);
  modbus_mapping_t* map = modbus_mapping_new(0, 0, 65536, 0);
  int listener = -1;
  for (int tries = 0; listener < 0 && tries < 100; ++tries) {
    listener = modbus_tcp_listen(ctx, 4);
    if (listener < 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  serving_ = true;
  std::vector<int> clients;
  uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
  while (!stop_ && listener >= 0) {
    fd_set rd;
    FD_ZERO(&rd);
    FD_SET(listener, &rd);
    int top = listener;
    for (int c : clients) FD_SET(c, &rd), top = std::max(top, c);
    timeval tv{0, 20000};
    if (select(top + 1, &rd, nullptr, nullptr, &tv) <= 0) continue;
    if (FD_ISSET(listener, &rd)) {
      int s = listener;
      const int c = modbus_tcp_accept(ctx, &s);
      if (c >= 0) clients.push_back(c);
    }
    for (size_t i = 0; i < clients.size();) {
      const int c = clients[i];
      if (!FD_ISSET(c, &rd)) {
        ++i;
        continue;
      }
      modbus_set_socket(ctx, c);
      const int rc = modbus_receive(ctx, query);
      if (rc <= 0) {
        close(c);
        clients.erase(clients.begin() + long(i));
        continue;
      }
      if (silent_) {
        ++i;
        continue;
      }
      std::lock_guard<std::mutex> lk(mu_);
      map->nb_registers = registers_;  // libmodbus refuses an address past it (exception 2)
      std::memcpy(map->tab_registers, regs_.data(), regs_.size() * sizeof(uint16_t));
      modbus_reply(ctx, query, rc, map);
      std::memcpy(regs_.data(), map->tab_registers, regs_.size() * sizeof(uint16_t));
      scan();
      ++i;
    }
  }
  for (int c : clients) close(c);
  if (listener >= 0) close(listener);
  modbus_mapping_free(map);
  modbus_free(ctx);
  serving_ = false;
}

void SimPlc::scan() {
  for (int slot = 0; slot < cfg_.ring_slots; ++slot) {
    SlotRegisters s;
    for (int k = 0; k < kSlotRegisters; ++k)
      s[size_t(k)] = regs_[size_t(cfg_.ring_base + kSlotRegisters * slot + k)];
    Received r;
    if (s[0] == seen_[size_t(slot)] || !decode_release(s, r.release, r.sequence)) continue;
    seen_[size_t(slot)] = r.sequence;
    const auto b = belt_.find(r.release.lane);
    r.belt = b == belt_.end() ? INT64_MIN : b->second;
    received_.push_back(r);
  }
}

void SimPlc::set_registers(int count) {
  registers_ = std::clamp(count, 1, 65536);
}

void SimPlc::set_silent(bool silent) {
  silent_ = silent;
}

void SimPlc::belt(int lane, int64_t count) {
  std::lock_guard<std::mutex> lk(mu_);
  belt_[lane] = count;
}

std::vector<SimPlc::Received> SimPlc::received() const {
  std::lock_guard<std::mutex> lk(mu_);
  return received_;
}

uint16_t SimPlc::heartbeat() const {
  std::lock_guard<std::mutex> lk(mu_);
  return regs_[size_t(cfg_.heartbeat_register)];
}

PackMl SimPlc::lane_state(int lane) const {
  std::lock_guard<std::mutex> lk(mu_);
  return PackMl(regs_[size_t(cfg_.lane_state_base + 2 * lane)]);
}

StateReason SimPlc::lane_reason(int lane) const {
  std::lock_guard<std::mutex> lk(mu_);
  return StateReason(regs_[size_t(cfg_.lane_state_base + 2 * lane + 1)]);
}

}  // namespace rangex
