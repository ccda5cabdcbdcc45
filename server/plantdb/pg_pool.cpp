#include "plantdb/pg_pool.h"

#include <cmath>

#include "core/error.h"

namespace rangex {

PgPool::PgPool(std::string conninfo, int keep, int connect_timeout_s, int statement_timeout_s,
               double hold_s)
    : conninfo_(std::move(conninfo)),
      where_(pg_where(conninfo_)),
      keep_(keep),
      connect_timeout_s_(connect_timeout_s),
      statement_timeout_s_(statement_timeout_s),
      hold_s_(hold_s) {}

PgPool::~PgPool() = default;

void PgPool::hold(const std::string& why) {
  down_ = why;
  down_at_ = Clock::now();
  idle_.clear();  // connections to a hung server would each wait out their bound again
}

void PgPool::refuse() {
  const double ago = std::chrono::duration<double>(Clock::now() - down_at_).count();
  const std::string again =
      probing_ ? "being tried again now"
               : "tried again in " + std::to_string(int(std::ceil(hold_s_ - ago))) + " s";
  throw Unavailable(join(down_, " (", int(ago), " s ago; ", again, ")"));
}

PgPool::Lease PgPool::take() {
  bool probe = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!down_.empty()) {
      if (probing_ || Clock::now() - down_at_ < std::chrono::duration<double>(hold_s_)) refuse();
      probing_ = probe = true;
    }
    while (!idle_.empty()) {
      std::unique_ptr<PgConnection> c = std::move(idle_.back());
      idle_.pop_back();
      if (c->ok()) return Lease(*this, std::move(c), probe);
    }
  }
  try {
    return Lease(
        *this, std::make_unique<PgConnection>(conninfo_, connect_timeout_s_, statement_timeout_s_),
        probe);
  } catch (const Unavailable& e) {
    std::lock_guard<std::mutex> lock(mu_);
    if (probe) probing_ = false;
    hold(e.what());
    throw;
  } catch (...) {  // refused otherwise (a bad string): the next request may try again
    std::lock_guard<std::mutex> lock(mu_);
    if (probe) probing_ = false;
    throw;
  }
}

void PgPool::give_back(std::unique_ptr<PgConnection> c, bool probe) {
  std::lock_guard<std::mutex> lock(mu_);
  if (probe) probing_ = false;
  if (c && !c->unanswered().empty()) return hold(c->unanswered());
  if (probe) down_.clear();  // it answered
  if (!c || !c->ok()) return;
  if (int(idle_.size()) < keep_) idle_.push_back(std::move(c));
}

}  // namespace rangex
