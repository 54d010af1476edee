// Starts a real voxeld on 127.0.0.1 with --port 0 and reads the bound port from its
// --port-file; stops it with SIGTERM (or kills it when the test is done). The child dies
// with the test process (PR_SET_PDEATHSIG) and logs to a file, so a crashed test never
// leaves a server running or holding the test runner's output pipe.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "tests/child_process.hpp"

namespace vox::test {

class ServerProcess {
 public:
  explicit ServerProcess(std::vector<std::string> extra_args = {}) {
    static int counter = 0;
    dir_ = std::filesystem::temp_directory_path() /
           ("voxeld_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::create_directories(dir_);
    const std::string port_file = (dir_ / "port").string();
    std::vector<std::string> args = {VOXELD_PATH, "--port",      "0",      "--bind",
                                     "127.0.0.1", "--port-file", port_file};
    // Defaults a test may override: every test client comes from 127.0.0.1, so the
    // per-address cap is off unless a test sets it.
    const std::vector<std::pair<std::string, std::string>> defaults = {
        {"--threads", "2"},
        {"--stats-interval", "0"},
        {"--log-level", "warn"},
        {"--http-port", "0"},  // off: a test that wants it sets --http-port auto
        {"--max-per-address", "0"},
        {"--max-handshaking-per-address", "0"},
        {"--world", (dir_ / "world").string()}};
    for (const auto& [flag, value] : defaults) {
      if (std::find(extra_args.begin(), extra_args.end(), flag) == extra_args.end()) {
        args.push_back(flag);
        args.push_back(value);
      }
    }
    args.insert(args.end(), extra_args.begin(), extra_args.end());
    if (std::find(extra_args.begin(), extra_args.end(), "--http-port") != extra_args.end()) {
      args.push_back("--http-port-file");
      args.push_back((dir_ / "http_port").string());
    }
    if (std::find(extra_args.begin(), extra_args.end(), "--metrics-port") != extra_args.end()) {
      args.push_back("--metrics-port-file");
      args.push_back((dir_ / "metrics_port").string());
    }
    pid_ = spawn_logged(std::move(args), (dir_ / "voxeld.log").string());
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (std::chrono::steady_clock::now() < deadline) {
      std::ifstream in(port_file);
      if (in >> port_ && port_ != 0) return;
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_)
        throw std::runtime_error("voxeld exited at start");
      std::this_thread::sleep_for(
          std::chrono::milliseconds(10));  // polling a file the child writes
    }
    throw std::runtime_error("voxeld did not report its port in time");
  }
  ~ServerProcess() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
    std::error_code ec;
    if (std::getenv("VOXEL_KEEP_SERVER_LOGS") == nullptr) std::filesystem::remove_all(dir_, ec);
  }
  uint16_t port() const { return port_; }
  std::filesystem::path log_path() const { return dir_ / "voxeld.log"; }
  // With --metrics-port: the bound metrics port (written just after the main port file).
  uint16_t metrics_port() const { return port_from("metrics_port"); }
  uint16_t port_from(const char* file) const {
    for (int i = 0; i < 500; ++i) {
      std::ifstream in(dir_ / file);
      uint16_t port = 0;
      if (in >> port && port != 0) return port;
      std::this_thread::sleep_for(
          std::chrono::milliseconds(10));  // polling a file the child writes
    }
    return 0;
  }
  // With --http-port: the bound HTTP port (written just after the main port file).
  uint16_t http_port() const { return port_from("http_port"); }
  pid_t pid() const { return pid_; }
  // SIGTERM, then the exit code (-1 when it did not exit within the timeout).
  int terminate(std::chrono::seconds timeout = std::chrono::seconds(10)) {
    ::kill(pid_, SIGTERM);
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return -1;
  }
  bool running() {
    int status = 0;
    return pid_ > 0 && waitpid(pid_, &status, WNOHANG) == 0;
  }

 private:
  pid_t pid_ = -1;
  uint16_t port_ = 0;
  std::filesystem::path dir_;
};

}  // namespace vox::test
