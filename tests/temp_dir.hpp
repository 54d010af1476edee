// A fresh, empty temporary directory for one test, removed with everything in it when the
// object goes, also when an assertion ends the test early. mkdtemp makes the name unique,
// so parallel or repeated runs never share one.
#pragma once

#include <stdlib.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>

namespace vox::test {

class TempDir {
 public:
  explicit TempDir(std::string_view tag) {
    std::string name =
        (std::filesystem::temp_directory_path() / ("voxel_" + std::string(tag) + "_XXXXXX"))
            .string();
    if (::mkdtemp(name.data()) == nullptr) {
      const int error = errno;  // before anything else can change it
      throw std::runtime_error("mkdtemp " + name + ": " + std::strerror(error));
    }
    path_ = name;
  }
  ~TempDir() {
    std::error_code ec;  // a destructor must not throw; a leftover is harmless
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::string string() const { return path_.string(); }
  std::filesystem::path operator/(const std::filesystem::path& p) const { return path_ / p; }
  // Implicit, so code that took the directory as a path takes a TempDir unchanged.
  operator const std::filesystem::path&() const { return path_; }  // NOLINT: by design

 private:
  std::filesystem::path path_;
};

}  // namespace vox::test
