// A real nats-server (Debian's) for the cluster tests: on 127.0.0.1, a port the server
// picks (read from its ports file), a user and password from a configuration file in a
// temporary directory (never on the command line). The child dies with the test process
// (tests/child_process.hpp); stop() and the destructor end it. restart() starts it again on the
// same port, as a NATS restart in production would.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "tests/child_process.hpp"
#include "tests/temp_dir.hpp"

namespace vox::test {

class NatsServer {
 public:
  static constexpr const char* kUser = "voxnode";
  static constexpr const char* kPassword = "test-only-secret";

  NatsServer() { start(-1); }
  ~NatsServer() { stop(); }
  NatsServer(const NatsServer&) = delete;
  NatsServer& operator=(const NatsServer&) = delete;

  std::string url() const { return "nats://127.0.0.1:" + std::to_string(port_); }
  int port() const { return port_; }

  void stop() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
  }
  void restart() {
    stop();
    start(port_);
  }

 private:
  static std::string binary() {
    for (const char* p : {"/usr/sbin/nats-server", "/usr/bin/nats-server"})
      if (std::filesystem::exists(p)) return p;
    throw std::runtime_error("nats-server not found (apt-get install nats-server)");
  }

  void start(int port) {
    const std::filesystem::path conf = dir_ / "nats.conf";
    {
      std::ofstream out(conf);
      out << "host: 127.0.0.1\nport: " << port << "\n"
          << "authorization { user: \"" << kUser << "\", password: \"" << kPassword << "\" }\n";
    }
    const std::filesystem::path ports = dir_ / "ports";
    std::filesystem::remove_all(ports);
    std::filesystem::create_directories(ports);
    std::vector<std::string> args{binary(), "-c", conf.string(), "--ports_file_dir",
                                  ports.string()};
    const std::string log = (dir_ / "nats.log").string();
    pid_ = spawn_logged(std::move(args), log, /*append=*/true);
    // The ports file: {"nats":["nats://127.0.0.1:PORT"], ...} ("client" in other versions)
    const std::regex client(R"re("(?:nats|client)":\["nats://[^"]*:(\d+)")re");
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (std::chrono::steady_clock::now() < deadline) {
      for (const auto& entry : std::filesystem::directory_iterator(ports)) {
        std::ifstream in(entry.path());
        const std::string text((std::istreambuf_iterator<char>(in)), {});
        std::smatch m;
        if (std::regex_search(text, m, client)) {
          port_ = std::stoi(m[1]);
          return;
        }
      }
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        throw std::runtime_error("nats-server exited at start (see " + log + ")");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));  // polling a file it writes
    }
    throw std::runtime_error("nats-server did not write its ports file in time");
  }

  TempDir dir_{"nats"};
  pid_t pid_ = -1;
  int port_ = 0;
};

}  // namespace vox::test
