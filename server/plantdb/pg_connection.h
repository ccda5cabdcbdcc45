// A PostgreSQL connection (libpq) that throws Error naming the statement and the server's
// complaint. libpq's header stays in the .cpp: the forwarder, the migrations and the chain
// check hold a PgConnection and nothing of libpq.
#pragma once
#include <optional>
#include <string>
#include <vector>

struct pg_conn;
struct pg_result;

namespace rangex {

// Rows of one result, as text (PostgreSQL's text format; NULL is nullopt).
class PgRows {
 public:
  PgRows() = default;
  explicit PgRows(pg_result* r);
  ~PgRows();
  PgRows(PgRows&& o) noexcept : r_(o.r_) { o.r_ = nullptr; }
  PgRows& operator=(PgRows&& o) noexcept;
  PgRows(const PgRows&) = delete;
  PgRows& operator=(const PgRows&) = delete;
  int rows() const;
  bool null(int row, int col) const;
  std::string str(int row, int col) const;  // "" for NULL
  long long i64(int row, int col) const;
  double dbl(int row, int col) const;

 private:
  pg_result* r_ = nullptr;
};

using PgParam = std::optional<std::string>;  // nullopt: NULL

// How long past its statement_timeout a statement's answer is waited for: the server's own
// cancellation, when it can still answer, comes first.
constexpr int kAnswerGrace_s = 5;

class PgConnection {
 public:
  // A libpq connection string ("host=... dbname=... sslmode=verify-full", or a URI);
  // passwords come from PGPASSFILE or ~/.pgpass, never the command line. connect_timeout
  // (seconds) is added unless the string sets one. A failure to connect is Unavailable.
  //
  // statement_timeout_s: the server cancels a statement that runs longer. One with no
  // answer kAnswerGrace_s after that (a hung host, a network that holds the packets, which
  // TCP keepalives do not see while the host acknowledges) is given up on: it fails with
  // Unavailable, and the connection is closed, since nobody knows what it did.
  explicit PgConnection(const std::string& conninfo, int connect_timeout_s = 5,
                        int statement_timeout_s = 60);
  ~PgConnection();
  PgConnection(const PgConnection&) = delete;
  PgConnection& operator=(const PgConnection&) = delete;

  PgRows exec(const std::string& sql);
  PgRows exec(const std::string& sql, const std::vector<PgParam>& params);
  bool ok() const;  // the connection still stands (false after a cut or a server restart)
  // Why a statement was given up on ("" while none was): the connection is closed then.
  const std::string& unanswered() const { return unanswered_; }
  // From another thread: a statement waiting on a server that answers nothing (a hung host)
  // fails at once, and so does each one after it. The connection must outlive the call.
  void interrupt() noexcept;
  // After a failure inside a transaction: ROLLBACK if the connection stands. Its own failure
  // is dropped: the first one is the one to report.
  void rollback_quietly() noexcept;
  // The server's address as the user gave it, without any password (for messages).
  const std::string& where() const { return where_; }

 private:
  [[noreturn]] void fail_statement(const std::string& sql, pg_result* r);
  [[noreturn]] void give_up(const std::string& sql);
  pg_result* answer(const std::string& sql);  // the statement's result, waited for in bounds

  pg_conn* c_ = nullptr;
  int wake_fd_ = -1;  // a duplicate of the socket's descriptor, for interrupt()
  std::string where_;
  int answer_wait_s_ = 0;
  std::string unanswered_;
};

// Text of a double that reads back to the same double (for hashed content).
std::string pg_exact(double v);

// A connection string's parts that name the server (host, port, dbname, user), for logs
// and errors: never its password.
std::string pg_where(const std::string& conninfo);

// A connection string given on a command line (`what`: "--db"), returned as it is; refused
// (Error) when it holds a password, which anyone on the machine reads in the process list.
std::string no_password(const std::string& conninfo, const std::string& what);

}  // namespace rangex
