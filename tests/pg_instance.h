// A real PostgreSQL server for a test: initdb and pg_ctl (Debian postgresql-15) in a scratch
// folder, listening on a Unix socket there only, so that tests never meet each other or a
// plant's database. As root the server runs as the `postgres` user (initdb refuses root).
// Missing binaries fail the test: the plant-wide tests are required to run.
#pragma once
#include <signal.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

namespace rangex::test {

class PgInstance {
 public:
  PgInstance() {
    bin_ = find_bin();
    std::string tmpl = (std::filesystem::temp_directory_path() / "rangex-pg-XXXXXX").string();
    dir_ = mkdtemp(tmpl.data());
    as_ = getuid() == 0 ? "runuser -u postgres -- " : "";
    if (getuid() == 0) run("chown postgres " + dir_);
    run(as_ + bin_ + "/initdb -D " + dir_ + "/data -A trust -U rangex -E UTF8 --no-sync > " + dir_ +
        "/initdb.log 2>&1");
    start();
  }
  ~PgInstance() {
    std::system(
        (as_ + bin_ + "/pg_ctl -D " + dir_ + "/data -m immediate -w stop >/dev/null 2>&1").c_str());
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  PgInstance(const PgInstance&) = delete;
  PgInstance& operator=(const PgInstance&) = delete;

  // The libpq connection string of the instance's `postgres` database.
  std::string conninfo() const { return "host=" + dir_ + " port=5432 user=rangex dbname=postgres"; }
  void start() {
    run(as_ + bin_ + "/pg_ctl -D " + dir_ + "/data -l " + dir_ + "/server.log -w -t 60 -o \"-k " +
        dir_ + " -p 5432 -c listen_addresses= -c fsync=off\" start > /dev/null");
  }
  void stop() {
    run(as_ + bin_ + "/pg_ctl -D " + dir_ + "/data -m fast -w -t 60 stop > /dev/null");
  }
  // The postmaster killed as a crash would (its backends follow it when they notice); the
  // next start recovers from the WAL.
  void kill9() {
    std::ifstream pidf(dir_ + "/data/postmaster.pid");
    long pid = 0;
    pidf >> pid;
    if (pid <= 0) throw std::runtime_error("PostgreSQL: no postmaster.pid to kill");
    ::kill(pid_t(pid), SIGKILL);
    // Its backends exit once they find the postmaster gone; a new start waits for them.
    for (int i = 0; i < 100 && ::kill(pid_t(pid), 0) == 0; ++i) usleep(50000);
    std::system(("pkill -9 -f -- '-D " + dir_ + "/data' >/dev/null 2>&1").c_str());
    usleep(200000);
    std::filesystem::remove(dir_ + "/data/postmaster.pid");
  }
  // Every process of the instance stopped (SIGSTOP) or let go on (SIGCONT): a frozen server
  // takes connections into its listen queue and answers nothing, as a hung host's would.
  void freeze() { signal_all("-STOP"); }
  void thaw() { signal_all("-CONT"); }
  const std::string& dir() const { return dir_; }

 private:
  static std::string find_bin() {
    if (const char* e = std::getenv("RANGEX_PG_BIN")) return e;
    for (const char* v : {"17", "16", "15", "14", "13"}) {
      const std::string b = std::string("/usr/lib/postgresql/") + v + "/bin";
      if (std::filesystem::exists(b + "/initdb")) return b;
    }
    throw std::runtime_error(
        "PostgreSQL's initdb and pg_ctl are not installed (Debian postgresql-15; "
        "scripts/install-deps.sh installs it): the plant-wide tests cannot run");
  }
  void signal_all(const std::string& sig) {
    std::ifstream pidf(dir_ + "/data/postmaster.pid");
    long pid = 0;
    pidf >> pid;
    if (pid <= 0) throw std::runtime_error("PostgreSQL: no postmaster.pid to signal");
    // The postmaster's children (the backends, their helpers), then the postmaster.
    run("pkill " + sig + " -P " + std::to_string(pid) + "; kill " + sig + " " +
        std::to_string(pid));
  }
  static void run(const std::string& cmd) {
    if (std::system(cmd.c_str()) != 0)
      throw std::runtime_error("PostgreSQL fixture: '" + cmd + "' failed");
  }
  std::string bin_, dir_, as_;
};

}  // namespace rangex::test
