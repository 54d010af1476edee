#include "options/option_values.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <stdexcept>

namespace vox::options {

int parse_args(const char* program, const std::vector<std::string>& args,
               const po::options_description& opts,
               const po::positional_options_description* positional, const char* synopsis,
               po::variables_map& vm, std::ostream& out, std::ostream& err) {
  try {
    po::command_line_parser parser(args);
    parser.options(opts);
    if (positional != nullptr) parser.positional(*positional);
    po::store(parser.run(), vm);
    if (vm.count("help")) {
      out << synopsis << "\n" << opts;
      return 0;
    }
    po::notify(vm);
  } catch (const po::error& e) {
    err << program << ": " << e.what() << " (see --help)\n";
    return 2;
  }
  return -1;
}

namespace {
template <size_t N>
std::array<float, N> parse_floats(const std::string& text, const char* what) {
  std::array<float, N> v{};
  const char* p = text.data();
  const char* end = text.data() + text.size();
  for (size_t i = 0; i < N; ++i) {
    if (p < end && *p == '+') ++p;
    auto [next, ec] = std::from_chars(p, end, v[i]);
    if (ec != std::errc() || !std::isfinite(v[i])) {
      throw std::invalid_argument(std::string(what) + " must be " + (N == 3 ? "X,Y,Z" : "X,Z") +
                                  " with finite numbers, got '" + text + "'");
    }
    p = next;
    if (i + 1 < N) {
      if (p == end || *p != ',')
        throw std::invalid_argument(std::string(what) + ": expected ',' in '" + text + "'");
      ++p;
    }
  }
  if (p != end)
    throw std::invalid_argument(std::string(what) + ": trailing characters in '" + text + "'");
  return v;
}
}  // namespace

std::array<float, 3> parse_vec3(const std::string& text, const char* what) {
  return parse_floats<3>(text, what);
}
std::array<float, 2> parse_vec2(const std::string& text, const char* what) {
  return parse_floats<2>(text, what);
}

std::chrono::milliseconds timeout_of(double seconds) {
  if (!(seconds > 0) || seconds > 86400)
    throw std::invalid_argument("--timeout must be in (0, 86400] seconds");
  return std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
}

std::pair<std::string, uint16_t> parse_server(const std::string& text) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0)
    throw std::invalid_argument("--server must be HOST:PORT, got '" + text + "'");
  unsigned port = 0;
  const char* p = text.data() + colon + 1;
  auto [end, ec] = std::from_chars(p, text.data() + text.size(), port);
  if (ec != std::errc() || end != text.data() + text.size() || port == 0 || port > 65535) {
    throw std::invalid_argument("--server port must be 1..65535, got '" + text + "'");
  }
  return {text.substr(0, colon), static_cast<uint16_t>(port)};
}

std::optional<size_t> parse_bytes(const std::string& text) {
  unsigned long long value = 0;
  const char* end = text.data() + text.size();
  auto [p, ec] = std::from_chars(text.data(), end, value);
  if (ec != std::errc() || p == text.data()) return std::nullopt;
  const std::string unit(p, end);
  int shift = 0;
  if (unit == "K" || unit == "KiB")
    shift = 10;
  else if (unit == "M" || unit == "MiB")
    shift = 20;
  else if (unit == "G" || unit == "GiB")
    shift = 30;
  else if (!unit.empty())
    return std::nullopt;
  if (value > (SIZE_MAX >> shift)) return std::nullopt;
  return static_cast<size_t>(value) << shift;
}

uint64_t parse_duration_s(const std::string& text, const char* what) {
  uint64_t n = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), n);
  const std::string unit(end, text.data() + text.size());
  uint64_t scale = 0;
  if (unit.empty() || unit == "s") scale = 1;
  if (unit == "m") scale = 60;
  if (unit == "h") scale = 3600;
  if (unit == "d") scale = 86400;
  if (unit == "w") scale = 7 * 86400;
  if (ec != std::errc() || end == text.data() || scale == 0 || n > (1ull << 40) / scale)
    throw std::invalid_argument(std::string(what) + ": '" + text +
                                "' is not a duration (a number with s, m, h, d or w)");
  return n * scale;
}

int64_t parse_time_ms(const std::string& text, const char* what, int64_t now_ms) {
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, s = 0;
  char tail = 0;
  std::string t = text;
  if (!t.empty() && (t.back() == 'Z' || t.back() == 'z')) t.pop_back();
  const int n =
      std::sscanf(t.c_str(), "%4d-%2d-%2dT%2d:%2d:%2d%c", &y, &mo, &d, &h, &mi, &s, &tail);
  // Digits only where the format has them (sscanf would take signs and spaces).
  const std::string shape = n == 3   ? "dddd-dd-dd"
                            : n == 5 ? "dddd-dd-ddTdd:dd"
                                     : "dddd-dd-ddTdd:dd:dd";
  bool digits = (n == 3 || n == 5 || n == 6) && t.size() == shape.size();
  for (size_t i = 0; digits && i < t.size(); ++i)
    digits =
        shape[i] == 'd' ? std::isdigit(static_cast<unsigned char>(t[i])) != 0 : t[i] == shape[i];
  if (digits && y >= 1970) {
    std::tm tm{};
    tm.tm_year = y - 1900, tm.tm_mon = mo - 1, tm.tm_mday = d;
    tm.tm_hour = h, tm.tm_min = mi, tm.tm_sec = s;
    const std::time_t at = timegm(&tm);
    std::tm back{};
    gmtime_r(&at, &back);  // a day or an hour out of range comes back as another one
    if (back.tm_year == y - 1900 && back.tm_mon == mo - 1 && back.tm_mday == d &&
        back.tm_hour == h && back.tm_min == mi && back.tm_sec == s)
      return static_cast<int64_t>(at) * 1000;
  }
  try {
    // A duration ago needs its unit: a bare number is more likely a mistyped time.
    if (text.empty() || !std::isalpha(static_cast<unsigned char>(text.back())))
      throw std::invalid_argument(text);
    return now_ms - static_cast<int64_t>(parse_duration_s(text, what)) * 1000;
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument(std::string(what) + ": '" + text +
                                "' is neither a time (2026-12-07T10:30:00, UTC) nor a duration "
                                "ago (30m, 2h, 7d)");
  }
}

}  // namespace vox::options
