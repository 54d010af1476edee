// Command-line option values, parsed strictly: shared by voxeld, voxel-cli and
// voxel-loadtest, so each flag of a kind reads and refuses the same way everywhere. Pure
// functions; any thread.
#pragma once

#include <array>
#include <boost/program_options.hpp>
#include <chrono>
#include <cstdint>
#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

namespace vox::options {

namespace po = boost::program_options;

// Parses args (without the program name) into vm. Returns -1 to go on, else the exit code
// to return: 0 after --help (the synopsis and options written to out), 2 for bad usage
// (one line on err, starting "PROGRAM: ").
int parse_args(const char* program, const std::vector<std::string>& args,
               const po::options_description& opts,
               const po::positional_options_description* positional, const char* synopsis,
               po::variables_map& vm, std::ostream& out, std::ostream& err);

// "X,Y,Z" of finite numbers; throws std::invalid_argument naming `what` otherwise.
std::array<float, 3> parse_vec3(const std::string& text, const char* what);
// "X,Z" of finite numbers.
std::array<float, 2> parse_vec2(const std::string& text, const char* what);
// A --timeout in seconds (> 0, at most a day) as a duration; throws std::invalid_argument.
std::chrono::milliseconds timeout_of(double seconds);
// "HOST:PORT"; throws std::invalid_argument.
std::pair<std::string, uint16_t> parse_server(const std::string& text);
// "1073741824", "512M", "2G", "64K" (binary units; KiB, MiB, GiB too) -> bytes; nullopt
// when malformed or past SIZE_MAX.
std::optional<size_t> parse_bytes(const std::string& text);
// "90", "90s", "30m", "12h", "7d", "2w" -> seconds (at most 2^40); throws
// std::invalid_argument naming `what`.
uint64_t parse_duration_s(const std::string& text, const char* what);
// A point in time as Unix milliseconds: "2026-12-07", "2026-12-07T10:30" or
// "2026-12-07T10:30:15" (UTC; a trailing Z allowed), or a duration before `now_ms` ("2h":
// two hours ago); throws std::invalid_argument naming `what`.
int64_t parse_time_ms(const std::string& text, const char* what, int64_t now_ms);

}  // namespace vox::options
