#include "options/config_file.hpp"

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <utility>

namespace vox::options {

namespace {

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return {};
  return s.substr(a, s.find_last_not_of(" \t\r") - a + 1);
}

// A key or value quoted into an error line: printable ASCII only, at most 80 characters.
std::string shown(const std::string& s) {
  std::string out;
  for (const char ch : s.substr(0, 80)) out += ch >= 0x20 && ch < 0x7f ? ch : '?';
  return s.size() > 80 ? out + "..." : out;
}

template <class F>
std::string shortest(F f) {  // the shortest text that reads back as f
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, f);
  return std::string(buf, r.ptr);
}

// One option's value as text, or nullopt for a type no voxeld flag has.
std::optional<std::vector<std::string>> value_text(const boost::any& v) {
  using V = std::vector<std::string>;
  if (const auto* s = boost::any_cast<std::string>(&v)) return V{*s};
  if (const auto* b = boost::any_cast<bool>(&v)) return V{*b ? "true" : "false"};
  if (const auto* i = boost::any_cast<int>(&v)) return V{std::to_string(*i)};
  if (const auto* l = boost::any_cast<long>(&v)) return V{std::to_string(*l)};
  if (const auto* u = boost::any_cast<unsigned>(&v)) return V{std::to_string(*u)};
  if (const auto* u = boost::any_cast<uint16_t>(&v)) return V{std::to_string(*u)};
  if (const auto* u = boost::any_cast<unsigned long>(&v)) return V{std::to_string(*u)};
  if (const auto* u = boost::any_cast<unsigned long long>(&v)) return V{std::to_string(*u)};
  if (const auto* d = boost::any_cast<double>(&v)) return V{shortest(*d)};
  if (const auto* f = boost::any_cast<float>(&v)) return V{shortest(*f)};
  if (const auto* list = boost::any_cast<V>(&v)) return *list;
  return std::nullopt;
}

}  // namespace

ConfigFile store_config_file(const std::string& path, const po::options_description& opts,
                             const std::set<std::string>& refused, po::variables_map& vm) {
  ConfigFile file;
  file.path = path;
  const auto error = [&file](int line, const std::string& key, const std::string& why) {
    std::string at = file.path + ":" + std::to_string(line) + ": ";
    if (!key.empty()) at += "key '" + shown(key) + "': ";
    file.errors.push_back(at + why);
  };
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    file.errors.push_back(path + ": cannot be read");
    return file;
  }
  // Each key's values in file order, with the line of each.
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, int>>>> keys;
  std::map<std::string, size_t> index;
  std::string text;
  int line = 0;
  size_t bytes = 0;
  constexpr size_t kMaxBytes = 1 << 20;  // a configuration, not a data file
  while (std::getline(in, text)) {
    ++line;
    bytes += text.size() + 1;
    if (bytes > kMaxBytes) {
      error(line, {}, "the file is over 1 MiB: not a configuration file");
      return file;
    }
    if (const size_t hash = text.find('#'); hash != std::string::npos) text.resize(hash);
    text = trim(text);
    if (text.empty()) continue;
    if (text.front() == '[') {
      error(line, {}, "sections are not used: write key = value");
      continue;
    }
    const size_t eq = text.find('=');
    if (eq == std::string::npos) {
      error(line, {}, "expected key = value, got '" + shown(text) + "'");
      continue;
    }
    const std::string key = trim(text.substr(0, eq)), value = trim(text.substr(eq + 1));
    const po::option_description* option = opts.find_nothrow(key, false);
    if (key.empty() || option == nullptr) {
      error(line, key, "not an option (voxeld --help lists them, without their --)");
      continue;
    }
    if (refused.count(key) != 0) {
      error(line, key, "not allowed in a configuration file");
      continue;
    }
    auto [at, fresh] = index.try_emplace(key, keys.size());
    if (fresh) keys.push_back({key, {}});
    keys[at->second].second.emplace_back(value, line);
    file.lines.try_emplace(key, line);
  }
  if (in.bad()) file.errors.push_back(path + ": read error");
  // Every value through the table's own parser, one key at a time, into a scratch map
  // first: nothing is stored unless every line is right.
  po::variables_map scratch;
  for (const auto& [key, values] : keys) {
    po::parsed_options parsed(&opts);
    po::option option(key, {});
    for (const auto& [value, at] : values) option.value.push_back(value);
    parsed.options.push_back(std::move(option));
    try {
      const po::option_description& d = opts.find(key, false);
      if (values.size() > 1 && !d.semantic()->is_composing() && d.semantic()->max_tokens() <= 1)
        throw po::error("set on line " + std::to_string(values.front().second) + " already");
      po::variables_map one;
      po::store(parsed, one);
    } catch (const po::error& e) {
      error(values.back().second, key, e.what());
    }
  }
  if (!file.errors.empty()) {
    std::sort(file.errors.begin(), file.errors.end(),
              [](const std::string& a, const std::string& b) {
                const auto line_of = [](const std::string& s) {
                  const size_t colon = s.find(':');
                  return colon == std::string::npos ? 0 : std::atoi(s.c_str() + colon + 1);
                };
                return line_of(a) < line_of(b);
              });
    return file;
  }
  for (const auto& [key, values] : keys) {
    po::parsed_options parsed(&opts);
    po::option option(key, {});
    for (const auto& [value, at] : values) option.value.push_back(value);
    parsed.options.push_back(std::move(option));
    po::store(parsed, vm);
  }
  return file;
}

void write_config_file(std::ostream& out, const po::options_description& opts,
                       const po::variables_map& vm, const std::set<std::string>& skipped) {
  for (const auto& d : opts.options()) {
    const std::string& key = d->long_name();
    if (key.empty() || skipped.count(key) != 0) continue;
    out << "\n# " << d->description() << "\n";
    const auto it = vm.find(key);
    const auto values =
        it == vm.end() || it->second.empty() ? std::nullopt : value_text(it->second.value());
    if (!values || values->empty()) {
      out << "# " << key << " =\n";
      continue;
    }
    for (const std::string& v : *values) out << key << " = " << v << "\n";
  }
}

}  // namespace vox::options
