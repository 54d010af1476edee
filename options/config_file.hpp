// A configuration file for a program_options table (voxeld --config): one `key = value`
// per line, the key a flag's long name without its dashes; `#` at the start of a line or
// after a space starts a comment; blank lines are skipped; a list flag takes one line per
// value. A value may be quoted ("a # b", " x", ""), with \" \\ and \n escapes inside.
// Read by hand, line by line, so that every error names the file, the line and the key
// (program_options' own parser names neither file nor line); the values go through the
// table's own parsers. Pure but for reading the file; any thread.
#pragma once

#include <boost/program_options.hpp>
#include <map>
#include <ostream>
#include <set>
#include <string>
#include <vector>

namespace vox::options {

namespace po = boost::program_options;

struct ConfigFile {
  std::string path;
  std::map<std::string, int> lines;  // key -> the line that set it (the first for a list)
  std::vector<std::string> errors;   // "PATH:LINE: key 'K': why", in line order
};

// Reads `path` (a regular file of at most 1 MiB; a UTF-8 byte order mark is skipped) and
// stores its values into `vm`. A key in `given` (set on the command line) is skipped
// whole, lists included: the command line wins. Keys in `refused` (--help, --config
// itself) are errors, as is a bare empty value (write "" for an empty text; a switch takes
// true or false). Nothing is stored when there is an error; at most 20 are reported.
ConfigFile store_config_file(const std::string& path, const po::options_description& opts,
                             const std::set<std::string>& refused,
                             const std::set<std::string>& given, po::variables_map& vm);

// The configuration in `vm` as a file store_config_file reads back to the same values:
// each option's description as a comment, then `key = value` (quoted when it must be; a
// list: a line per value). A value left at its default, or none, is written commented out,
// so that reading the file back leaves it a default. Keys in `skipped` are left out.
void write_config_file(std::ostream& out, const po::options_description& opts,
                       const po::variables_map& vm, const std::set<std::string>& skipped);

// Every option's value in `vm` as text, as write_config_file writes it (a list: a value
// each; none: empty), by key; keys in `skipped` left out. What a reload compares.
std::map<std::string, std::vector<std::string>> effective_values(
    const po::options_description& opts, const po::variables_map& vm,
    const std::set<std::string>& skipped);

}  // namespace vox::options
