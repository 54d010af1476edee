#include "options/config_file.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <utility>

namespace vox::options {

namespace {

constexpr size_t kMaxBytes = 1 << 20;  // a configuration, not a data file
constexpr size_t kMaxErrors = 20;

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

// `text` without a comment: from a '#' at its start or after a space or tab.
std::string without_comment(const std::string& text) {
  for (size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '#' && (i == 0 || text[i - 1] == ' ' || text[i - 1] == '\t'))
      return text.substr(0, i);
  }
  return text;
}

// The value after '=' (`raw`, untrimmed): quoted or bare. nullopt with `why` set when
// malformed.
std::optional<std::string> parse_value(const std::string& raw, std::string& why) {
  const std::string t = trim(raw);
  if (t.empty() || t.front() != '"') {
    const std::string bare = trim(without_comment(raw));
    if (bare.empty()) why = "no value (write \"\" for an empty text; a switch takes true or false)";
    return bare.empty() ? std::nullopt : std::optional<std::string>(bare);
  }
  std::string value;
  size_t i = 1;
  for (; i < t.size() && t[i] != '"'; ++i) {
    if (t[i] != '\\') {
      value += t[i];
      continue;
    }
    if (++i == t.size()) break;
    if (t[i] == 'n') {
      value += '\n';
    } else if (t[i] == '"' || t[i] == '\\') {
      value += t[i];
    } else {
      why = "unknown escape \\" + shown(std::string(1, t[i])) + " in a quoted value";
      return std::nullopt;
    }
  }
  if (i >= t.size()) {
    why = "a quoted value without its closing \"";
    return std::nullopt;
  }
  if (!trim(without_comment(" " + t.substr(i + 1))).empty()) {
    why = "text after the quoted value";
    return std::nullopt;
  }
  return value;
}

std::string quoted_if_needed(const std::string& v) {
  const bool plain =
      !v.empty() && v == trim(v) && v.find_first_of("#\"\\\n\r") == std::string::npos;
  if (plain) return v;
  std::string out = "\"";
  for (const char ch : v) {
    if (ch == '"' || ch == '\\') {
      out += '\\';
      out += ch;
    } else if (ch == '\n') {
      out += "\\n";
    } else {
      out += ch;
    }
  }
  return out + "\"";
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

po::parsed_options one_option(const po::options_description& opts, const std::string& key,
                              std::vector<std::string> values) {
  po::parsed_options parsed(&opts);
  po::option option(key, std::move(values));
  parsed.options.push_back(std::move(option));
  return parsed;
}

}  // namespace

ConfigFile store_config_file(const std::string& path, const po::options_description& opts,
                             const std::set<std::string>& refused,
                             const std::set<std::string>& given, po::variables_map& vm) {
  ConfigFile file;
  file.path = path;
  std::vector<std::pair<int, std::string>> errors;
  const auto error = [&](int line, const std::string& key, const std::string& why) {
    std::string at = file.path + ":" + std::to_string(line) + ": ";
    if (!key.empty()) at += "key '" + shown(key) + "': ";
    errors.emplace_back(line, at + why);
  };
  const auto finish = [&] {
    // By line, in the order found within one (std::sort on (line, order): stable_sort's
    // temporary buffer trips AddressSanitizer's new/free check with clang 14's libstdc++).
    std::vector<size_t> order(errors.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&errors](size_t a, size_t b) {
      return std::pair(errors[a].first, a) < std::pair(errors[b].first, b);
    });
    std::vector<std::pair<int, std::string>> sorted;
    for (const size_t i : order) sorted.push_back(std::move(errors[i]));
    errors.swap(sorted);
    for (auto& [line, text] : errors) {
      if (file.errors.size() == kMaxErrors) {
        file.errors.push_back(file.path + ": " + std::to_string(errors.size() - kMaxErrors) +
                              " more errors not shown");
        break;
      }
      file.errors.push_back(std::move(text));
    }
    return file;
  };
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    file.errors.push_back(path + ": cannot be read");
    return file;
  }
  if (!S_ISREG(st.st_mode) || static_cast<size_t>(st.st_size) > kMaxBytes) {
    file.errors.push_back(path + ": not a configuration file (a regular file of at most 1 MiB)");
    return file;
  }
  std::ifstream in(path, std::ios::binary);
  std::string all(kMaxBytes + 1, '\0');
  in.read(all.data(), static_cast<std::streamsize>(all.size()));
  all.resize(static_cast<size_t>(in.gcount()));
  if (in.bad() || all.size() > kMaxBytes) {
    file.errors.push_back(path + ": cannot be read whole");
    return file;
  }
  if (all.starts_with("\xef\xbb\xbf")) all.erase(0, 3);  // a byte order mark (Notepad)
  // Each key's values in file order, with the line of each.
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, int>>>> keys;
  std::map<std::string, size_t> index;
  int line = 0;
  size_t at = 0;
  while (at <= all.size() && errors.size() <= kMaxErrors) {
    const size_t end = std::min(all.find('\n', at), all.size());
    const std::string raw = all.substr(at, end - at);
    at = end + 1;
    ++line;
    const std::string text = trim(without_comment(raw));
    if (text.empty()) continue;
    if (text.front() == '[') {
      error(line, {}, "sections are not used: write key = value");
      continue;
    }
    const size_t eq = without_comment(raw).find('=');  // a prefix of raw: the same index
    if (eq == std::string::npos) {
      error(line, {}, "expected key = value, got '" + shown(text) + "'");
      continue;
    }
    const std::string key = trim(raw.substr(0, eq));
    const po::option_description* option = opts.find_nothrow(key, false);
    if (key.empty() || option == nullptr) {
      error(line, key, "not an option (voxeld --help lists them, without their --)");
      continue;
    }
    if (refused.count(key) != 0) {
      error(line, key, "not allowed in a configuration file");
      continue;
    }
    std::string why;
    const std::optional<std::string> value = parse_value(raw.substr(eq + 1), why);
    if (!value) {
      error(line, key, why);
      continue;
    }
    auto [it, fresh] = index.try_emplace(key, keys.size());
    if (fresh) keys.push_back({key, {}});
    keys[it->second].second.emplace_back(*value, line);
    file.lines.try_emplace(key, line);
  }
  // Every value through the table's own parser (each of a list alone, so an error names
  // its own line), into scratch maps: nothing is stored unless every line is right.
  for (const auto& [key, values] : keys) {
    const po::option_description& d = opts.find(key, false);
    const bool list = d.semantic()->is_composing() || d.semantic()->max_tokens() > 1;
    if (values.size() > 1 && !list) {
      error(values[1].second, key, "set on line " + std::to_string(values[0].second) + " already");
      continue;
    }
    for (const auto& [value, where] : values) {
      try {
        po::variables_map one;
        po::store(one_option(opts, key, {value}), one);
      } catch (const po::error& e) {
        error(where, key, e.what());
      }
    }
  }
  if (!errors.empty()) return finish();
  for (const auto& [key, values] : keys) {
    if (given.count(key) != 0) continue;  // the command line's value wins, a list's too
    std::vector<std::string> tokens;
    for (const auto& [value, where] : values) tokens.push_back(value);
    po::store(one_option(opts, key, std::move(tokens)), vm);
  }
  return file;
}

std::map<std::string, std::vector<std::string>> effective_values(
    const po::options_description& opts, const po::variables_map& vm,
    const std::set<std::string>& skipped) {
  std::map<std::string, std::vector<std::string>> out;
  for (const auto& d : opts.options()) {
    const std::string& key = d->long_name();
    if (key.empty() || skipped.count(key) != 0) continue;
    const auto it = vm.find(key);
    const auto values =
        it == vm.end() || it->second.empty() ? std::nullopt : value_text(it->second.value());
    out[key] = values ? *values : std::vector<std::string>{};
  }
  return out;
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
    const char* prefix = it->second.defaulted() ? "# " : "";  // read back, still a default
    for (const std::string& v : *values)
      out << prefix << key << " = " << quoted_if_needed(v) << "\n";
  }
}

}  // namespace vox::options
