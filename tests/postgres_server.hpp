// A real PostgreSQL server for the store tests, from Debian's packages: initdb in a
// temporary directory, listening only on a Unix socket there (no TCP port), stopped and
// removed when the object goes. As root (CI), the server runs as the `postgres` user, since
// initdb refuses root. Tests get a fresh database each (create_database).
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>

#include "tests/temp_dir.hpp"

namespace vox::test {

class PostgresServer {
 public:
  PostgresServer() : bin_(find_bindir()) {
    port_ = 20000 + static_cast<int>(std::random_device{}() % 40000);
    as_root_ = ::geteuid() == 0;
    if (as_root_) {
      // mkdtemp makes it 0700: root must still reach the socket once postgres owns it.
      std::filesystem::permissions(dir_, std::filesystem::perms::others_exec,
                                   std::filesystem::perm_options::add);
      sh("chown postgres:postgres " + dir_.string());
    }
    run_as_pg(bin_ + "/initdb -A trust -U postgres -E UTF8 --no-sync -D " + data() + " > " +
              (dir_ / "initdb.log").string() + " 2>&1");
    start();
  }
  ~PostgresServer() { stop(); }  // then dir_ goes, with the server's files
  PostgresServer(const PostgresServer&) = delete;
  PostgresServer& operator=(const PostgresServer&) = delete;

  void start() {
    run_as_pg(bin_ + "/pg_ctl -D " + data() + " -l " + (dir_ / "server.log").string() +
              " -w -t 60 -o \"-k " + dir_.string() + " -p " + std::to_string(port_) +
              " -c listen_addresses=''\" start > /dev/null");
    running_ = true;
  }
  void stop() {
    if (!running_) return;
    running_ = false;
    run_as_pg(bin_ + "/pg_ctl -D " + data() + " -m fast -w -t 60 stop > /dev/null 2>&1", false);
  }

  // A connection URI for `db` (the socket directory as host).
  std::string uri(const std::string& db = "postgres") const {
    return "postgresql:///" + db + "?host=" + dir_.string() + "&port=" + std::to_string(port_) +
           "&user=postgres";
  }
  // Runs `sql` in database `db` with psql (tests that set a database up by hand).
  void sql(const std::string& db, const std::string& sql) {
    sh(bin_ + "/psql -q -v ON_ERROR_STOP=1 -h " + dir_.string() + " -p " + std::to_string(port_) +
       " -U postgres -d " + db + " -c '" + escape(sql) + "' > /dev/null");
  }
  // A new empty database; returns its URI.
  std::string create_database(const std::string& name) {
    sh(bin_ + "/psql -q -h " + dir_.string() + " -p " + std::to_string(port_) +
       " -U postgres -d postgres -c 'CREATE DATABASE " + name + "' > /dev/null");
    return uri(name);
  }

 private:
  static std::string find_bindir() {
    for (int v = 20; v >= 13; --v) {
      const std::string dir = "/usr/lib/postgresql/" + std::to_string(v) + "/bin";
      if (std::filesystem::exists(dir + "/initdb")) return dir;
    }
    throw std::runtime_error("PostgreSQL server binaries not found (apt-get install postgresql)");
  }
  std::string data() const { return (dir_ / "data").string(); }
  void run_as_pg(const std::string& cmd, bool check = true) {
    sh(as_root_ ? "runuser -u postgres -- sh -c '" + escape(cmd) + "'" : cmd, check);
  }
  static std::string escape(const std::string& s) {
    std::string out;
    for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out;
  }
  static void sh(const std::string& cmd, bool check = true) {
    if (std::system(cmd.c_str()) != 0 && check) throw std::runtime_error("failed: " + cmd);
  }

  std::string bin_;  // before dir_: no directory is made when the binaries are missing
  TempDir dir_{"pg"};
  int port_ = 0;
  bool as_root_ = false;
  bool running_ = false;
};

// One server for the whole test program, started on first use and stopped at its exit;
// each call makes a fresh database named `prefix` and a number. Main thread.
inline std::string fresh_shared_database(const std::string& prefix) {
  static PostgresServer server;
  static int n = 0;
  return server.create_database(prefix + std::to_string(n++));
}

}  // namespace vox::test
