// Starting a real server program from a test: the child dies with the test process
// (PR_SET_PDEATHSIG), so a crashed test never leaves one running, and writes its output to
// a log file, never to the test runner's pipe.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <stdexcept>
#include <string>
#include <vector>

extern char** environ;

namespace vox::test {

// Starts args[0] with `args` (its path, not looked up), stdout and stderr to `log`
// (truncated, or appended to); returns its pid.
inline pid_t spawn_logged(std::vector<std::string> args, const std::string& log,
                          bool append = false) {
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {  // child: only async-signal-safe calls until exec
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(127);
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | (append ? O_APPEND : O_TRUNC), 0644);
    if (fd >= 0) {
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      ::close(fd);
    }
    ::execve(argv[0], argv.data(), environ);
    ::_exit(127);
  }
  return pid;
}

}  // namespace vox::test
