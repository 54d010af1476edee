// A configuration file for a program_options table (voxeld --config): one `key = value`
// per line, the key a flag's long name without its dashes; `#` starts a comment; blank
// lines are skipped; a list flag takes one line per value. Read by hand, line by line,
// so that every error names the file, the line and the key (program_options' own
// parser names neither file nor line); the values go through the table's own parsers.
// Pure but for reading the file; any thread.
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

// Reads `path` and stores its values into `vm`, under what is there already: a value
// stored before (the command line's) wins, a list's values join those before. Keys in
// `refused` (--help, --config itself) are errors. Nothing is stored when there is an error.
ConfigFile store_config_file(const std::string& path, const po::options_description& opts,
                             const std::set<std::string>& refused, po::variables_map& vm);

// The effective value of every option of `opts` in `vm` as a file store_config_file reads
// back to the same values: each option's description as a comment, then `key = value`
// (a list: a line per value; no value: the key commented out). Keys in `skipped` are left
// out.
void write_config_file(std::ostream& out, const po::options_description& opts,
                       const po::variables_map& vm, const std::set<std::string>& skipped);

}  // namespace vox::options
