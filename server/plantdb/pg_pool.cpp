#include "plantdb/pg_pool.h"

namespace rangex {

PgPool::PgPool(std::string conninfo, int keep, int connect_timeout_s)
    : conninfo_(std::move(conninfo)),
      where_(pg_where(conninfo_)),
      keep_(keep),
      connect_timeout_s_(connect_timeout_s) {}

PgPool::~PgPool() = default;

PgPool::Lease PgPool::take() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    while (!idle_.empty()) {
      std::unique_ptr<PgConnection> c = std::move(idle_.back());
      idle_.pop_back();
      if (c->ok()) return Lease(*this, std::move(c));
    }
  }
  return Lease(*this, std::make_unique<PgConnection>(conninfo_, connect_timeout_s_));
}

void PgPool::give_back(std::unique_ptr<PgConnection> c) {
  if (!c || !c->ok()) return;
  std::lock_guard<std::mutex> lock(mu_);
  if (int(idle_.size()) < keep_) idle_.push_back(std::move(c));
}

}  // namespace rangex
