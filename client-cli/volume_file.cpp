#include "client-cli/volume_file.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <new>
#include <sstream>
#include <utility>

#include "client-cli/nifti_file.hpp"
#include "client-cli/nrrd_file.hpp"
#include "client-cli/sample_data.hpp"

namespace vox::cli {
namespace {

bool is_space(char c) {
  return c == ' ' || c == '\n' || c == '\r' || c == '\t' || c == '\f' || c == '\v';
}

class Tokens {
 public:
  explicit Tokens(std::string_view text) : p_(text.data()), end_(text.data() + text.size()) {}
  // Next token, or empty at the end of the text.
  std::string_view next() {
    while (p_ < end_ && is_space(*p_)) ++p_;
    const char* start = p_;
    while (p_ < end_ && !is_space(*p_)) ++p_;
    return {start, static_cast<size_t>(p_ - start)};
  }
  size_t remaining() const { return static_cast<size_t>(end_ - p_); }

 private:
  const char* p_;
  const char* end_;
};

bool ends_with(const std::string& s, std::string_view suffix) {
  if (s.size() < suffix.size()) return false;
  for (size_t i = 0; i < suffix.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(s[s.size() - suffix.size() + i])) != suffix[i])
      return false;
  }
  return true;
}

}  // namespace

void check_volume_dims(const std::string& path, const std::array<int, 3>& dims) {
  size_t samples = 1;
  for (int d : dims) {
    if (d < 2)
      throw VolumeError(path + ": every dimension must be at least 2 samples, got " +
                        std::to_string(d));
    samples *= static_cast<size_t>(d);
    if (samples > kMaxVolumeSamples)
      throw VolumeError(path + ": volume too large (over 2^31 samples)");
  }
}

size_t volume_sample_count(const std::array<int, 3>& dims) {
  return static_cast<size_t>(dims[0]) * dims[1] * dims[2];
}

std::array<int, 3> parse_dims(const std::string& text) {
  std::array<int, 3> dims{};
  const char* p = text.data();
  const char* end = text.data() + text.size();
  for (int a = 0; a < 3; ++a) {
    auto [next, ec] = std::from_chars(p, end, dims[a]);
    if (ec != std::errc() || dims[a] <= 0)
      throw VolumeError("--dims must be X,Y,Z with positive integers, got '" + text + "'");
    p = next;
    if (a < 2) {
      if (p == end || *p != ',')
        throw VolumeError("--dims must be X,Y,Z with positive integers, got '" + text + "'");
      ++p;
    }
  }
  if (p != end)
    throw VolumeError("--dims must be X,Y,Z with positive integers, got '" + text + "'");
  return dims;
}

mesh::Volume read_text_volume(const std::string& path) {
  const MappedFile file(path);
  const auto bytes = file.bytes();
  return parse_text_volume({reinterpret_cast<const char*>(bytes.data()), bytes.size()}, path);
}

mesh::Volume parse_text_volume(std::string_view text, const std::string& path) {
  Tokens tokens(text);
  mesh::Volume volume;
  const char* names[3] = {"xdim", "ydim", "zdim"};
  for (int a = 0; a < 3; ++a) {
    const std::string_view t = tokens.next();
    if (t.empty()) throw VolumeError(path + ": missing " + names[a] + " in the header");
    auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), volume.dims[a]);
    if (ec != std::errc() || end != t.data() + t.size()) {
      throw VolumeError(path + ": " + names[a] + " is not an integer: " + quoted_excerpt(t));
    }
  }
  check_volume_dims(path, volume.dims);
  const size_t n = volume_sample_count(volume.dims);
  // Each value takes a byte and a separator: a header may not make us allocate for more
  // values than the file can hold (17 bytes once asked for 632 MB).
  const size_t room = (tokens.remaining() + 1) / 2;
  if (n > room) {
    throw VolumeError(path + ": expected " + std::to_string(n) +
                      " values, the file has room for at most " + std::to_string(room));
  }
  volume.values.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const std::string_view t = tokens.next();
    if (t.empty()) {
      throw VolumeError(path + ": expected " + std::to_string(n) + " values, found " +
                        std::to_string(i));
    }
    float v = 0;
    const char* first = t.data() + (t.size() > 1 && t[0] == '+' ? 1 : 0);
    auto [end, ec] = std::from_chars(first, t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size()) {
      throw VolumeError(path + ": value " + std::to_string(i) +
                        " is not a number: " + quoted_excerpt(t));
    }
    if (!std::isfinite(v))
      throw VolumeError(path + ": value " + std::to_string(i) + " is not finite");
    volume.values[i] = v;
  }
  if (!tokens.next().empty()) {
    throw VolumeError(path + ": more than the " + std::to_string(n) +
                      " values the header declares");
  }
  return volume;
}

RawVolumeFile::RawVolumeFile(const std::string& path, std::array<int, 3> dims)
    : dims_(dims), file_(checked(path, dims)) {
  const size_t n = volume_sample_count(dims);
  if (file_.bytes().size() != n * sizeof(float)) {
    throw VolumeError(path + ": raw float32 volume of " + std::to_string(dims[0]) + "x" +
                      std::to_string(dims[1]) + "x" + std::to_string(dims[2]) + " needs " +
                      std::to_string(n * sizeof(float)) + " bytes, file has " +
                      std::to_string(file_.bytes().size()));
  }
}

MappedFile RawVolumeFile::checked(const std::string& path, const std::array<int, 3>& dims) {
  static_assert(std::endian::native == std::endian::little,
                "raw volumes are mapped as they are: a little-endian host is assumed");
  check_volume_dims(path, dims);
  return MappedFile(path);
}

std::span<const float> RawVolumeFile::values() const {
  return {reinterpret_cast<const float*>(file_.bytes().data()),
          file_.bytes().size() / sizeof(float)};
}

void RawVolumeFile::release(size_t begin, size_t end) const {
  file_.release(begin * sizeof(float), end * sizeof(float));
}

mesh::Volume read_raw_volume(const std::string& path, std::array<int, 3> dims) {
  const RawVolumeFile file(path, dims);
  const std::span<const float> values = file.values();
  for (size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i]))
      throw VolumeError(path + ": value " + std::to_string(i) + " is not finite");
  }
  mesh::Volume volume;
  volume.dims = dims;
  volume.values.assign(values.begin(), values.end());
  return volume;
}

mesh::Volume read_volume(const std::string& path, const std::optional<std::array<int, 3>>& dims) {
  return dims ? read_raw_volume(path, *dims) : read_text_volume(path);
}

LoadedVolume load_volume(const std::string& path, const std::optional<std::array<int, 3>>& dims) {
  try {
    if (!dims && (ends_with(path, ".nii") || ends_with(path, ".nii.gz"))) return read_nifti(path);
    if (!dims && (ends_with(path, ".nrrd") || ends_with(path, ".nhdr"))) return read_nrrd(path);
    if (!dims) {  // another name: a NIfTI or NRRD file is still known by its first bytes
      const MappedFile file(path);
      const auto b = file.bytes();
      const bool gzip = b.size() >= 2 && b[0] == 0x1f && b[1] == 0x8b;
      const bool nifti =
          b.size() >= kNiftiHeaderSize && (std::memcmp(b.data() + 344, "n+1", 4) == 0 ||
                                           std::memcmp(b.data() + 344, "ni1", 4) == 0);
      if (gzip || nifti) return parse_nifti(b, path);
      if (b.size() >= 4 && std::memcmp(b.data(), "NRRD", 4) == 0) return parse_nrrd(b, path);
    }
    return {read_volume(path, dims), std::nullopt};
  } catch (const std::bad_alloc&) {
    throw VolumeError(path + ": not enough memory for the samples it declares");
  }
}

}  // namespace vox::cli
