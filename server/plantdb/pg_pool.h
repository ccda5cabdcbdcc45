// PostgreSQL connections shared by a server's request threads (a PgConnection serves one
// thread at a time): a request takes one, or opens one, and gives it back when done; a
// connection that broke is dropped, so the next request opens a fresh one.
//
// A database that does not answer (a connection that cannot be made, a statement given up
// on) is named at once to every request for hold_s; then one request tries it again while
// the others are still refused. So a hung database costs a reader its bound once, and not
// each of the server's threads its bound over and over.
#pragma once
#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "plantdb/pg_connection.h"

namespace rangex {

class PgPool {
 public:
  PgPool(std::string conninfo, int keep = 4, int connect_timeout_s = 5,
         int statement_timeout_s = 10, double hold_s = 5);
  ~PgPool();

  // A connection held until it goes out of scope.
  class Lease {
   public:
    Lease(PgPool& pool, std::unique_ptr<PgConnection> c, bool probe)
        : pool_(pool), c_(std::move(c)), probe_(probe) {}
    ~Lease() { pool_.give_back(std::move(c_), probe_); }
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    PgConnection& operator*() { return *c_; }
    PgConnection* operator->() { return c_.get(); }

   private:
    PgPool& pool_;
    std::unique_ptr<PgConnection> c_;
    bool probe_;  // the one request trying a database that did not answer
  };

  // Throws Unavailable naming the database when it cannot connect, or while it is held as
  // not answering.
  Lease take();
  const std::string& where() const { return where_; }

 private:
  using Clock = std::chrono::steady_clock;
  void give_back(std::unique_ptr<PgConnection> c, bool probe);
  void hold(const std::string& why);  // under mu_
  [[noreturn]] void refuse();         // under mu_

  const std::string conninfo_, where_;
  const int keep_, connect_timeout_s_, statement_timeout_s_;
  const double hold_s_;
  std::mutex mu_;
  std::vector<std::unique_ptr<PgConnection>> idle_;
  std::string down_;           // why the database is held as not answering ("": it answers)
  Clock::time_point down_at_;  // when it last did not
  bool probing_ = false;       // a request is trying it again
};

}  // namespace rangex
