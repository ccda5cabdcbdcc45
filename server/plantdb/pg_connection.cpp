#include "plantdb/pg_connection.h"

#include <libpq-fe.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "core/error.h"

namespace rangex {

PgRows::PgRows(pg_result* r) : r_(r) {}
PgRows::~PgRows() {
  if (r_) PQclear(r_);
}
PgRows& PgRows::operator=(PgRows&& o) noexcept {
  if (this != &o) {
    if (r_) PQclear(r_);
    r_ = o.r_;
    o.r_ = nullptr;
  }
  return *this;
}
int PgRows::rows() const {
  return r_ ? PQntuples(r_) : 0;
}
bool PgRows::null(int row, int col) const {
  return !r_ || PQgetisnull(r_, row, col);
}
std::string PgRows::str(int row, int col) const {
  return null(row, col) ? std::string() : std::string(PQgetvalue(r_, row, col));
}
long long PgRows::i64(int row, int col) const {
  return null(row, col) ? 0 : std::strtoll(PQgetvalue(r_, row, col), nullptr, 10);
}
double PgRows::dbl(int row, int col) const {
  return null(row, col) ? 0.0 : std::strtod(PQgetvalue(r_, row, col), nullptr);
}

std::string pg_where(const std::string& conninfo) {
  char* err = nullptr;
  PQconninfoOption* opts = PQconninfoParse(conninfo.c_str(), &err);
  if (!opts) {
    std::string why = err ? err : "cannot be parsed";
    if (err) PQfreemem(err);
    while (!why.empty() && why.back() == '\n') why.pop_back();
    fail("results_db: ", why);
  }
  std::string out;
  for (PQconninfoOption* o = opts; o->keyword; ++o)
    for (const char* k : {"host", "hostaddr", "port", "dbname", "user"})
      if (std::strcmp(o->keyword, k) == 0 && o->val && *o->val)
        out.append(out.empty() ? "" : " ").append(k).append("=").append(o->val);
  PQconninfoFree(opts);
  return out.empty() ? "the default PostgreSQL server" : out;
}

std::string no_password(const std::string& conninfo, const std::string& what) {
  PQconninfoOption* opts = PQconninfoParse(conninfo.c_str(), nullptr);
  if (!opts) return conninfo;  // unreadable: the connection's own error says so
  bool has = false;
  for (PQconninfoOption* o = opts; o->keyword; ++o)
    if (std::strcmp(o->keyword, "password") == 0 && o->val && *o->val) has = true;
  PQconninfoFree(opts);
  if (has)
    fail(what,
         " holds a password, which anyone on this machine can read from the process "
         "list: put it in a password file (PGPASSFILE, ~/.pgpass or passfile=...)");
  return conninfo;
}

PgConnection::PgConnection(const std::string& conninfo, int connect_timeout_s,
                           int statement_timeout_s)
    : where_(pg_where(conninfo)), answer_wait_s_(statement_timeout_s + kAnswerGrace_s) {
  if (statement_timeout_s < 1) fail("PostgreSQL at ", where_, ": a statement needs >= 1 s");
  // A URI takes its timeout as a parameter; a key=value string as one more key. Later keys
  // win in key=value strings, so the user's own connect_timeout is kept by putting ours first.
  const bool uri = conninfo.rfind("postgres://", 0) == 0 || conninfo.rfind("postgresql://", 0) == 0;
  // A cut network must not hold a statement forever: TCP keepalives and a user timeout
  // (ignored on Unix sockets), unless the string sets its own.
  std::string full = conninfo;
  if (!uri)
    full = "connect_timeout=" + std::to_string(connect_timeout_s) +
           " keepalives=1 keepalives_idle=10 keepalives_interval=5 keepalives_count=3 "
           "tcp_user_timeout=30000 " +
           conninfo;
  c_ = PQconnectdb(full.c_str());
  if (!c_ || PQstatus(c_) != CONNECTION_OK) {
    std::string why = c_ ? PQerrorMessage(c_) : "out of memory";
    while (!why.empty() && (why.back() == '\n' || why.back() == ' ')) why.pop_back();
    if (c_) PQfinish(c_);
    c_ = nullptr;
    throw Unavailable(join("PostgreSQL at ", where_, ": cannot connect: ", why));
  }
  // Our own descriptor of the connection's socket, for interrupt(): libpq may close its own
  // at any time, and its number be reused by another socket before we shut it down.
  wake_fd_ = ::dup(PQsocket(c_));
  // Notices (e.g. "relation already exists, skipping") are not errors; keep them off stderr.
  PQsetNoticeProcessor(
      c_, [](void*, const char*) {}, nullptr);
  // Statements are sent and their answers waited for with poll(), within answer_wait_s_.
  PQsetnonblocking(c_, 1);
  try {
    exec("SET statement_timeout = '" + std::to_string(statement_timeout_s) + "s'");
  } catch (...) {  // no destructor runs for a constructor that throws
    if (c_) PQfinish(c_);
    ::close(wake_fd_);
    throw;
  }
}

PgConnection::~PgConnection() {
  if (c_) PQfinish(c_);
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

void PgConnection::interrupt() noexcept {
  // shutdown() ends the socket itself, under every descriptor of it: the thread in libpq
  // wakes to an ended stream.
  if (wake_fd_ >= 0) ::shutdown(wake_fd_, SHUT_RDWR);
}

bool PgConnection::ok() const {
  return c_ && PQstatus(c_) == CONNECTION_OK;
}

namespace {
std::string first_line(const std::string& sql) {
  const std::string head = sql.substr(0, sql.find('\n'));
  return head.size() > 80 ? head.substr(0, 77) + "..." : head;
}
}  // namespace

PgRows PgConnection::exec(const std::string& sql) {
  return exec(sql, {});
}

PgRows PgConnection::exec(const std::string& sql, const std::vector<PgParam>& params) {
  if (!c_)
    throw Unavailable(join("PostgreSQL at ", where_, ": '", first_line(sql),
                           "': not sent, the connection was closed: ", unanswered_));
  std::vector<const char*> values;
  values.reserve(params.size());
  for (const PgParam& p : params) values.push_back(p ? p->c_str() : nullptr);
  const int sent = params.empty() ? PQsendQuery(c_, sql.c_str())
                                  : PQsendQueryParams(c_, sql.c_str(), int(values.size()), nullptr,
                                                      values.data(), nullptr, nullptr, 0);
  if (!sent) fail_statement(sql, nullptr);
  return PgRows(answer(sql));
}

namespace {
using Clock = std::chrono::steady_clock;
// Until the socket is ready for `events` (an error counts: libpq reads it), or false at
// the deadline.
bool wait_socket(int fd, short events, Clock::time_point until) {
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now()).count();
    if (left <= 0) return false;
    pollfd p{fd, events, 0};
    const int n = ::poll(&p, 1, int(std::min<long long>(left, 60'000)));
    if (n > 0 || (n < 0 && errno != EINTR)) return true;
  }
}
}  // namespace

// PQexec's semantics (the last result, or the first that failed), with every wait bounded.
pg_result* PgConnection::answer(const std::string& sql) {
  const Clock::time_point until = Clock::now() + std::chrono::seconds(answer_wait_s_);
  // Send all of it, reading meanwhile: a server may answer before it has read everything.
  // A connection that broke has no socket (-1): PQgetResult then reports it at once, where
  // poll() would wait out the deadline on it.
  for (int f; (f = PQflush(c_)) != 0;) {
    if (f < 0 || PQsocket(c_) < 0) fail_statement(sql, nullptr);
    if (!wait_socket(PQsocket(c_), POLLIN | POLLOUT, until)) give_up(sql);
    if (!PQconsumeInput(c_)) break;
  }
  pg_result* kept = nullptr;
  for (;;) {
    while (PQisBusy(c_) && PQsocket(c_) >= 0) {
      if (!wait_socket(PQsocket(c_), POLLIN, until)) {
        if (kept) PQclear(kept);
        give_up(sql);
      }
      if (!PQconsumeInput(c_)) break;
    }
    pg_result* r = PQgetResult(c_);
    if (!r) break;
    const ExecStatusType st = PQresultStatus(r);
    const bool failed = st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK;
    if (kept && PQresultStatus(kept) != PGRES_COMMAND_OK &&
        PQresultStatus(kept) != PGRES_TUPLES_OK) {
      PQclear(r);  // the first failure is the one to report
    } else {
      if (kept) PQclear(kept);
      kept = r;
    }
    if (failed && PQstatus(c_) == CONNECTION_BAD) break;
  }
  const ExecStatusType st = kept ? PQresultStatus(kept) : PGRES_FATAL_ERROR;
  if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) fail_statement(sql, kept);
  return kept;
}

void PgConnection::fail_statement(const std::string& sql, pg_result* r) {
  std::string why = r ? PQresultErrorMessage(r) : "";
  if (why.empty()) why = PQerrorMessage(c_);
  if (r) PQclear(r);
  while (!why.empty() && (why.back() == '\n' || why.back() == ' ')) why.pop_back();
  fail("PostgreSQL at ", where_, ": '", first_line(sql), "': ", why);
}

void PgConnection::give_up(const std::string& sql) {
  unanswered_ = join("PostgreSQL at ", where_, ": '", first_line(sql), "': no answer within ",
                     answer_wait_s_, " s (the server, its host or the network holds it)");
  PQfinish(c_);
  c_ = nullptr;
  // Our duplicate of the socket would keep it open: end it. The descriptor stays ours until
  // the destructor, so that interrupt() from another thread never touches a reused number.
  if (wake_fd_ >= 0) ::shutdown(wake_fd_, SHUT_RDWR);
  throw Unavailable(unanswered_);
}

std::string pg_exact(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

void PgConnection::rollback_quietly() noexcept {
  if (!ok()) return;
  try {
    exec("ROLLBACK");
  } catch (...) {
  }
}

}  // namespace rangex
