// voxel-cli's commands as a library, so tests run them in-process as well as through the
// executable. Each returns the process exit code: 0 ok, 1 failure, 2 bad usage.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

namespace vox::cli {

int run_cli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

int mesh_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int demo_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int info_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
// kind: brush, explode, smooth, paint or stamp.
int edit_command(const std::string& kind, const std::vector<std::string>& args, std::ostream& out,
                 std::ostream& err);
int script_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int watch_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int export_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
// world info|log|verify WORLD: the durable world, read-only; world migrate (world_migrate.cpp).
int world_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int world_migrate(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
// world info|verify of a cluster world's database (world_migrate.cpp).
int cluster_world_command(const std::string& action, const std::string& uri, std::ostream& out,
                          std::ostream& err);
// keygen --out NAME: an Ed25519 key pair; token --key FILE ...: a signed player token.
int keygen_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int token_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int region_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
// ray | ground | sample (query_command.cpp)
int query_command(const std::string& kind, const std::vector<std::string>& args, std::ostream& out,
                  std::ostream& err);
// action: players, kick, ban, unban, bans or rollback (admin_command.cpp).
int admin_command(const std::string& action, const std::vector<std::string>& args,
                  std::ostream& out, std::ostream& err);
int slice_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace vox::cli
