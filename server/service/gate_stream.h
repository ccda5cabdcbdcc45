// The stream a worker serves one request through, for a connection from the HTTP gate: the
// request head the gate read comes first, then the connection (plain or TLS, below). Reads
// never go beyond what httplib asks for, so the next request stays for the gate.
#pragma once
#include <httplib.h>

#include <string>

namespace rangex {

// Waits up to sec for the socket to be ready for events; false on timeout.
bool wait_for_socket(int fd, short events, time_t sec);

class GateStream : public httplib::Stream {
 public:
  GateStream(int fd, std::string& head, time_t read_s, time_t write_s)
      : fd_(fd), read_s_(read_s), write_s_(write_s), head_(head) {}
  bool is_readable() const override;
  bool is_writable() const override;
  ssize_t read(char* ptr, size_t size) override;
  void get_remote_ip_and_port(std::string& ip, int& port) const override;
  void get_local_ip_and_port(std::string& ip, int& port) const override;
  socket_t socket() const override { return fd_; }

 protected:
  virtual ssize_t read_more(char* ptr, size_t size) = 0;  // past the head
  virtual bool more_ready() const { return false; }       // read without waiting

  int fd_;
  time_t read_s_, write_s_;

 private:
  std::string& head_;
  size_t at_ = 0;
};

}  // namespace rangex
