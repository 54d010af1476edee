#include "client-cli/volume_file.hpp"

#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

namespace vox::cli {
namespace {

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw VolumeError(path + ": cannot open: " + std::strerror(errno));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) throw VolumeError(path + ": read error");
  return std::move(buffer).str();
}

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

void check_dims(const std::string& path, const std::array<int, 3>& dims) {
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

size_t sample_count(const std::array<int, 3>& dims) {
  return static_cast<size_t>(dims[0]) * dims[1] * dims[2];
}

}  // namespace

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
  return parse_text_volume(read_file(path), path);
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
      throw VolumeError(path + ": " + names[a] + " is not an integer: '" +
                        std::string(t.substr(0, 32)) + "'");
    }
  }
  check_dims(path, volume.dims);
  const size_t n = sample_count(volume.dims);
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
      throw VolumeError(path + ": value " + std::to_string(i) + " is not a number: '" +
                        std::string(t.substr(0, 32)) + "'");
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

mesh::Volume read_raw_volume(const std::string& path, std::array<int, 3> dims) {
  check_dims(path, dims);
  const size_t n = sample_count(dims);
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw VolumeError(path + ": cannot open: " + std::strerror(errno));
  const auto size = static_cast<size_t>(in.tellg());
  if (size != n * sizeof(float)) {
    throw VolumeError(path + ": raw float32 volume of " + std::to_string(dims[0]) + "x" +
                      std::to_string(dims[1]) + "x" + std::to_string(dims[2]) + " needs " +
                      std::to_string(n * sizeof(float)) + " bytes, file has " +
                      std::to_string(size));
  }
  in.seekg(0);
  mesh::Volume volume;
  volume.dims = dims;
  volume.values.resize(n);
  if (!in.read(reinterpret_cast<char*>(volume.values.data()),
               static_cast<std::streamsize>(n * sizeof(float)))) {
    throw VolumeError(path + ": read error");
  }
  if constexpr (std::endian::native == std::endian::big) {
    for (float& v : volume.values)
      v = std::bit_cast<float>(__builtin_bswap32(std::bit_cast<uint32_t>(v)));
  }
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(volume.values[i]))
      throw VolumeError(path + ": value " + std::to_string(i) + " is not finite");
  }
  return volume;
}

mesh::Volume read_volume(const std::string& path, const std::optional<std::array<int, 3>>& dims) {
  return dims ? read_raw_volume(path, *dims) : read_text_volume(path);
}

}  // namespace vox::cli
