#include "client-cli/nrrd_file.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <optional>
#include <set>

namespace vox::cli {
namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

std::string shown(std::string_view s) { return quoted_excerpt(s); }

SampleType type_of(std::string_view value, const std::string& path) {
  static const std::pair<const char*, SampleType> kNames[] = {
      {"uchar", SampleType::kU8},
      {"unsigned char", SampleType::kU8},
      {"uint8", SampleType::kU8},
      {"uint8_t", SampleType::kU8},
      {"signed char", SampleType::kI8},
      {"int8", SampleType::kI8},
      {"int8_t", SampleType::kI8},
      {"short", SampleType::kI16},
      {"short int", SampleType::kI16},
      {"signed short", SampleType::kI16},
      {"signed short int", SampleType::kI16},
      {"int16", SampleType::kI16},
      {"int16_t", SampleType::kI16},
      {"ushort", SampleType::kU16},
      {"unsigned short", SampleType::kU16},
      {"unsigned short int", SampleType::kU16},
      {"uint16", SampleType::kU16},
      {"uint16_t", SampleType::kU16},
      {"int", SampleType::kI32},
      {"signed int", SampleType::kI32},
      {"int32", SampleType::kI32},
      {"int32_t", SampleType::kI32},
      {"uint", SampleType::kU32},
      {"unsigned int", SampleType::kU32},
      {"uint32", SampleType::kU32},
      {"uint32_t", SampleType::kU32},
      {"float", SampleType::kF32},
      {"double", SampleType::kF64},
  };
  const std::string name = lower(value);
  for (const auto& [n, t] : kNames)
    if (name == n) return t;
  throw VolumeError(path + ": NRRD type " + shown(value) + " is not supported");
}

template <class T>
T number(std::string_view s, const char* field, const std::string& path) {
  T v{};
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size())
    throw VolumeError(path + ": NRRD " + field + ": " + shown(s) + " is not a number");
  return v;
}

std::vector<std::string_view> words(std::string_view s) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    const size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t') ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
  return out;
}

// "(a,b,c) (d,e,f) (g,h,i)": each vector's length; "none" or a bad vector gives 0.
std::array<float, 3> direction_lengths(std::string_view value, const std::string& path) {
  std::array<float, 3> out{};
  size_t axis = 0, i = 0;
  while (i < value.size()) {
    while (i < value.size() && (value[i] == ' ' || value[i] == '\t')) ++i;
    if (i >= value.size()) break;
    if (axis == 3) throw VolumeError(path + ": NRRD space directions: more than 3 vectors");
    if (value[i] != '(') {
      const size_t end = value.find_first_of(" \t", i);
      if (value.substr(i, end - i) != "none")
        throw VolumeError(path + ": NRRD space directions: " + shown(value) + " is malformed");
      ++axis;
      i = end == std::string_view::npos ? value.size() : end;
      continue;
    }
    const size_t close = value.find(')', i);
    if (close == std::string_view::npos)
      throw VolumeError(path + ": NRRD space directions: " + shown(value) + " is malformed");
    double sum = 0;
    std::string_view inner = value.substr(i + 1, close - i - 1);
    while (!inner.empty()) {
      const size_t comma = inner.find(',');
      sum += std::pow(number<double>(trim(inner.substr(0, comma)), "space directions", path), 2);
      inner = comma == std::string_view::npos ? std::string_view{} : inner.substr(comma + 1);
    }
    const double length = std::sqrt(sum);
    out[axis++] = std::isfinite(length) && length > 0 ? static_cast<float>(length) : 0.0f;
    i = close + 1;
  }
  if (axis != 3) throw VolumeError(path + ": NRRD space directions: need 3 vectors");
  return out;
}

// Applies one "field: value" line to the header.
void apply_field(const std::string& field, std::string_view value, NrrdHeader& h, int& rank,
                 bool& have_endian, const std::string& path) {
  if (field == "type") {
    h.type = type_of(value, path);
  } else if (field == "dimension") {
    rank = number<int>(value, "dimension", path);
    if (rank != 3)
      throw VolumeError(path + ": NRRD dimension is " + std::to_string(rank) + "; 3 is needed");
  } else if (field == "sizes") {
    const auto w = words(value);
    if (w.size() != 3)
      throw VolumeError(path + ": NRRD sizes: " + shown(value) + " must be 3 numbers");
    for (int a = 0; a < 3; ++a) h.dims[a] = number<int>(w[a], "sizes", path);
  } else if (field == "spacings") {
    const auto w = words(value);
    if (w.size() != 3)
      throw VolumeError(path + ": NRRD spacings: " + shown(value) + " must be 3 numbers");
    std::array<float, 3> s{};
    for (int a = 0; a < 3; ++a) {
      const double v = w[a] == "nan" ? 0.0 : number<double>(w[a], "spacings", path);
      s[a] = std::isfinite(v) && v > 0 ? static_cast<float>(v) : 0.0f;
    }
    h.spacing = s;
  } else if (field == "space directions") {
    h.spacing = direction_lengths(value, path);
  } else if (field == "encoding") {
    const std::string e = lower(value);
    if (e == "raw")
      h.encoding = NrrdEncoding::kRaw;
    else if (e == "gzip" || e == "gz")
      h.encoding = NrrdEncoding::kGzip;
    else if (e == "ascii" || e == "text" || e == "txt")
      h.encoding = NrrdEncoding::kAscii;
    else
      throw VolumeError(path + ": NRRD encoding " + shown(value) +
                        " is not supported (raw, gzip, ascii are)");
  } else if (field == "endian") {
    const std::string e = lower(value);
    if (e != "little" && e != "big")
      throw VolumeError(path + ": NRRD endian " + shown(value) + " is neither little nor big");
    h.big_endian = e == "big";
    have_endian = true;
  } else if (field == "data file" || field == "datafile") {
    if (std::any_of(value.begin(), value.end(), [](char c) { return c < 0x20 || c == 0x7f; }))
      throw VolumeError(path + ": NRRD data file " + shown(value) + " has control characters");
    if (value.empty() || value.find(' ') != std::string_view::npos || value == "LIST")
      throw VolumeError(path + ": NRRD data file " + shown(value) +
                        ": only one file name is supported");
    h.data_file = std::string(value);
  } else if (field == "line skip" || field == "lineskip") {
    h.line_skip = number<int>(value, "line skip", path);
    if (h.line_skip < 0) throw VolumeError(path + ": NRRD line skip is negative");
  } else if (field == "byte skip" || field == "byteskip") {
    h.byte_skip = number<long long>(value, "byte skip", path);
    if (h.byte_skip < -1) throw VolumeError(path + ": NRRD byte skip below -1");
  }
  // Other fields (content, space, space origin, kinds, centers, ...) do not change the mesh.
}

// The bytes after `lines` newline-ended lines of `data`.
std::span<const uint8_t> after_lines(std::span<const uint8_t> data, int lines,
                                     const std::string& path) {
  size_t at = 0;
  for (int l = 0; l < lines; ++l) {
    while (at < data.size() && data[at] != '\n') ++at;
    if (at == data.size()) throw VolumeError(path + ": NRRD line skip goes past the data");
    ++at;
  }
  return data.subspan(at);
}

bool is_separator(char c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t' || c == ','; }

void decode_ascii(std::span<const uint8_t> data, size_t n, float* out, const std::string& path) {
  const char* p = reinterpret_cast<const char*>(data.data());
  const char* end = p + data.size();
  for (size_t i = 0; i < n; ++i) {
    while (p < end && is_separator(*p)) ++p;
    if (p == end) {
      throw VolumeError(path + ": NRRD ascii data end at value " + std::to_string(i) + " of " +
                        std::to_string(n));
    }
    if (*p == '+') ++p;
    double v = 0;
    auto [next, ec] = std::from_chars(p, end, v);
    if (ec == std::errc::result_out_of_range) {  // 1e-400 underflows to 0; 1e400 is refused
      const std::string_view text(p, static_cast<size_t>(next - p));
      if (text.find("e-") != std::string_view::npos || text.find("E-") != std::string_view::npos) {
        ec = {};
        v = 0;
      }
    }
    if (ec != std::errc() || (next != end && !is_separator(*next)) ||
        !std::isfinite(static_cast<float>(v))) {
      throw VolumeError(path + ": NRRD ascii value " + std::to_string(i) +
                        " is not a finite float32 number");
    }
    out[i] = static_cast<float>(v);
    p = next;
  }
}

}  // namespace

NrrdHeader parse_nrrd_header(std::string_view text, const std::string& path) {
  if (text.size() < 8 || text.substr(0, 4) != "NRRD" ||
      !std::all_of(text.begin() + 4, text.begin() + 8, [](char c) { return c >= '0' && c <= '9'; }))
    throw VolumeError(path + ": not a NRRD file (no NRRD000N magic)");
  NrrdHeader h;
  int rank = 0;
  std::set<std::string> seen;
  bool have_type = false, have_sizes = false, have_encoding = false, have_endian = false;
  size_t at = text.find('\n');
  while (true) {
    if (at == std::string_view::npos || at >= kMaxNrrdHeaderBytes) {
      if (at != std::string_view::npos || text.size() > kMaxNrrdHeaderBytes)
        throw VolumeError(path + ": NRRD header longer than " +
                          std::to_string(kMaxNrrdHeaderBytes) + " bytes");
      break;  // a detached header may end at the end of the file
    }
    ++at;
    const size_t eol = text.find('\n', at);
    std::string_view line =
        text.substr(at, eol == std::string_view::npos ? text.size() - at : eol - at);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty()) {  // the blank line: data follow
      h.header_bytes = eol == std::string_view::npos ? text.size() : eol + 1;
      break;
    }
    at = eol;
    h.header_bytes = eol == std::string_view::npos ? text.size() : eol + 1;
    if (line[0] == '#') continue;
    if (line.find(":=") != std::string_view::npos) continue;  // key/value pair
    const size_t colon = line.find(": ");
    if (colon == std::string_view::npos)
      throw VolumeError(path + ": NRRD header line " + shown(line) + " is not 'field: value'");
    const std::string field = lower(trim(line.substr(0, colon)));
    if (!seen.insert(field).second)
      throw VolumeError(path + ": NRRD field " + shown(field) + " appears twice");
    apply_field(field, trim(line.substr(colon + 2)), h, rank, have_endian, path);
    have_type |= field == "type";
    have_sizes |= field == "sizes";
    have_encoding |= field == "encoding";
  }
  if (!have_type || rank == 0 || !have_sizes || !have_encoding)
    throw VolumeError(path + ": NRRD header lacks one of type, dimension, sizes, encoding");
  check_volume_dims(path, h.dims);
  if (!have_endian && sample_size(h.type) > 1 && h.encoding != NrrdEncoding::kAscii)
    throw VolumeError(path + ": NRRD header lacks the endian field for " +
                      sample_type_name(h.type) + " samples");
  if (h.byte_skip == -1 && h.encoding != NrrdEncoding::kRaw)
    throw VolumeError(path + ": NRRD byte skip -1 needs raw encoding");
  return h;
}

LoadedVolume parse_nrrd(std::span<const uint8_t> file, const std::string& path) {
  const std::string_view text(reinterpret_cast<const char*>(file.data()),
                              std::min(file.size(), kMaxNrrdHeaderBytes + 1));
  const NrrdHeader h = parse_nrrd_header(text, path);
  std::optional<MappedFile> detached;
  std::span<const uint8_t> data = file.subspan(std::min(h.header_bytes, file.size()));
  std::string data_path = path;
  if (!h.data_file.empty()) {
    data_path = (std::filesystem::path(path).parent_path() / h.data_file).string();
    detached.emplace(data_path);
    data = detached->bytes();
  }
  data = after_lines(data, h.line_skip, data_path);
  const size_t n = volume_sample_count(h.dims);
  const size_t bytes = n * sample_size(h.type);
  LoadedVolume loaded;
  loaded.spacing = h.spacing;
  loaded.volume.dims = h.dims;
  switch (h.encoding) {
    case NrrdEncoding::kRaw: {
      const size_t skip = h.byte_skip == -1 ? (data.size() >= bytes ? data.size() - bytes : 0)
                                            : static_cast<size_t>(h.byte_skip);
      if (skip > data.size() || data.size() - skip < bytes) {
        throw VolumeError(data_path + ": the NRRD header declares " + std::to_string(bytes) +
                          " bytes of samples, the data have " +
                          std::to_string(data.size() > skip ? data.size() - skip : 0));
      }
      loaded.volume.values.resize(n);
      decode_samples(data.subspan(skip, bytes), n, h.type, h.big_endian, 1.0, 0.0,
                     loaded.volume.values.data(), data_path);
      break;
    }
    case NrrdEncoding::kGzip: {
      GzipReader gz(data, data_path);
      gz.check_can_hold(static_cast<uint64_t>(h.byte_skip) + bytes, "byte skip and samples");
      gz.skip(static_cast<size_t>(h.byte_skip), "byte skip");
      read_gzip_samples(gz, n, h.type, h.big_endian, 1.0, 0.0, loaded.volume.values, data_path);
      break;
    }
    case NrrdEncoding::kAscii: {
      const size_t skip = static_cast<size_t>(h.byte_skip);
      if (skip > data.size() || (data.size() - skip + 1) / 2 < n) {
        throw VolumeError(data_path + ": the NRRD header declares " + std::to_string(n) +
                          " ascii values, the data have room for fewer");
      }
      loaded.volume.values.resize(n);
      decode_ascii(data.subspan(skip), n, loaded.volume.values.data(), data_path);
      break;
    }
  }
  return loaded;
}

LoadedVolume read_nrrd(const std::string& path) {
  const MappedFile file(path);
  return parse_nrrd(file.bytes(), path);
}

}  // namespace vox::cli
