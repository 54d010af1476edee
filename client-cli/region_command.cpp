// voxel-cli region add|list|remove: an admin manages protected regions over the protocol
// (docs/PROTOCOL.md 4.9), with an admin token (--token or VOXEL_TOKEN).
#include <charconv>
#include <cmath>
#include <ostream>

#include "client-cli/cli_options.hpp"
#include "client-cli/commands.hpp"
#include "client-cli/server_request.hpp"

namespace vox::cli {
namespace {

constexpr const char* kSynopsis =
    "usage: voxel-cli region add --min X,Y,Z --max X,Y,Z [--name N] [--owner ID]... "
    "[--protect build|explode|both]\n"
    "       voxel-cli region list\n"
    "       voxel-cli region remove ID\n"
    "(with an admin token: --token or VOXEL_TOKEN)";

// Sends one command and waits for its RegionResult.
wire::RegionResult run_command(const po::variables_map& vm, wire::Envelope command) {
  command.mutable_region_command()->set_request_id(1);
  return server_request(
             vm, command,
             [](const wire::Envelope& m) {
               return m.has_region_result() && m.region_result().request_id() == 1;
             },
             "RegionResult")
      .region_result();
}

std::string describe(const wire::Region& r) {
  std::string s = std::to_string(r.id()) + "  '" + r.name() + "'  (" +
                  std::to_string(r.box().min_x()) + "," + std::to_string(r.box().min_y()) + "," +
                  std::to_string(r.box().min_z()) + ")..(" + std::to_string(r.box().max_x()) + "," +
                  std::to_string(r.box().max_y()) + "," + std::to_string(r.box().max_z()) + ")  ";
  s += r.protect_build() && r.protect_explode() ? "build+explode"
       : r.protect_build()                      ? "build"
                                                : "explode";
  s += "  owners:";
  if (r.owners().empty()) s += " none";
  for (const std::string& o : r.owners()) s += " " + o;
  if (!r.created_by().empty()) s += "  by " + r.created_by();
  return s;
}

int refused(const wire::RegionResult& r, std::ostream& err) {
  err << "voxel-cli: refused: " << wire::RegionResult::Status_Name(r.status()) << ": " << r.reason()
      << "\n";
  return 1;
}

}  // namespace

int region_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  po::options_description opts = network_options("region");
  opts.add_options()("action", po::value<std::string>()->required(), "add, list or remove")(
      "id", po::value<uint64_t>(), "remove: the region's id")(
      "min", po::value<std::string>(), "add: X,Y,Z, the box's lowest sample")(
      "max", po::value<std::string>(), "add: X,Y,Z, the box's highest sample (inclusive)")(
      "name", po::value<std::string>()->default_value(""), "add: a name for people")(
      "owner", po::value<std::vector<std::string>>()->composing(),
      "add: a player id that may edit inside (repeat for more)")(
      "protect", po::value<std::string>()->default_value("both"),
      "add: what non-owners may not do inside: build, explode or both");
  po::positional_options_description positional;
  positional.add("action", 1).add("id", 1);
  po::variables_map vm;
  const int rc = parse_options(args, opts, &positional, kSynopsis, vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&]() -> int {
    const std::string action = vm["action"].as<std::string>();
    wire::Envelope m;
    auto* command = m.mutable_region_command();
    if (action == "list") {
      uint64_t after = 0;
      size_t count = 0;
      for (;;) {
        command->mutable_list()->set_after_id(after);
        const wire::RegionResult r = run_command(vm, m);
        if (r.status() != wire::RegionResult::OK) return refused(r, err);
        for (const wire::Region& region : r.regions()) out << describe(region) << "\n";
        count += static_cast<size_t>(r.regions_size());
        if (!r.more() || r.regions_size() == 0) break;
        after = r.regions(r.regions_size() - 1).id();
      }
      out << count << " protected region" << (count == 1 ? "" : "s") << "\n";
      return 0;
    }
    if (action == "remove") {
      if (!vm.count("id")) throw std::invalid_argument("region remove needs the region's ID");
      command->set_remove(vm["id"].as<uint64_t>());
    } else if (action == "add") {
      if (!vm.count("min") || !vm.count("max"))
        throw std::invalid_argument("region add needs --min and --max");
      auto* add = command->mutable_add();
      const auto lo = parse_corner(vm["min"].as<std::string>(), "--min");
      const auto hi = parse_corner(vm["max"].as<std::string>(), "--max");
      auto* b = add->mutable_box();
      b->set_min_x(lo[0]), b->set_min_y(lo[1]), b->set_min_z(lo[2]);
      b->set_max_x(hi[0]), b->set_max_y(hi[1]), b->set_max_z(hi[2]);
      add->set_name(vm["name"].as<std::string>());
      if (vm.count("owner"))
        for (const std::string& o : vm["owner"].as<std::vector<std::string>>()) add->add_owners(o);
      const std::string protect = vm["protect"].as<std::string>();
      if (protect != "build" && protect != "explode" && protect != "both")
        throw std::invalid_argument("--protect must be build, explode or both");
      add->set_protect_build(protect != "explode");
      add->set_protect_explode(protect != "build");
    } else {
      throw std::invalid_argument("region action must be add, list or remove, got '" + action +
                                  "'");
    }
    const wire::RegionResult r = run_command(vm, m);
    if (r.status() != wire::RegionResult::OK) return refused(r, err);
    for (const wire::Region& region : r.regions())
      out << (action == "add" ? "added " : "removed ") << describe(region) << "\n";
    return 0;
  });
}

}  // namespace vox::cli
