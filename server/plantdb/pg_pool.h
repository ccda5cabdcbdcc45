// PostgreSQL connections shared by a server's request threads (a PgConnection serves one
// thread at a time): a request takes one, or opens one, and gives it back when done; a
// connection that broke is dropped, so the next request opens a fresh one.
#pragma once
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "plantdb/pg_connection.h"

namespace rangex {

class PgPool {
 public:
  PgPool(std::string conninfo, int keep = 4, int connect_timeout_s = 5);
  ~PgPool();

  // A connection held until it goes out of scope.
  class Lease {
   public:
    Lease(PgPool& pool, std::unique_ptr<PgConnection> c) : pool_(pool), c_(std::move(c)) {}
    ~Lease() { pool_.give_back(std::move(c_)); }
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    PgConnection& operator*() { return *c_; }
    PgConnection* operator->() { return c_.get(); }

   private:
    PgPool& pool_;
    std::unique_ptr<PgConnection> c_;
  };

  Lease take();  // throws Error naming the database when it cannot connect
  const std::string& where() const { return where_; }

 private:
  void give_back(std::unique_ptr<PgConnection> c);
  const std::string conninfo_, where_;
  const int keep_, connect_timeout_s_;
  std::mutex mu_;
  std::vector<std::unique_ptr<PgConnection>> idle_;
};

}  // namespace rangex
