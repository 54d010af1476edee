// voxel-cli keygen / token: what a game's backend does to let its players in, for
// development and tests: an Ed25519 key pair in two files, and signed player tokens
// (server/auth/player_token.hpp; docs/PROTOCOL.md "Player tokens").
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <iterator>
#include <ostream>
#include <sstream>

#include "client-cli/cli_options.hpp"
#include "client-cli/commands.hpp"
#include "server/auth/player_token.hpp"

namespace vox::cli {
namespace {

// Creates `path` (never over an existing file) with `mode` and writes `text`.
void write_new_file(const std::string& path, const std::string& text, mode_t mode) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, mode);
  if (fd < 0) throw std::runtime_error(path + ": " + std::strerror(errno));
  const bool ok = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  ::close(fd);
  if (!ok) throw std::runtime_error(path + ": could not be written");
}

}  // namespace

int keygen_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  po::options_description opts("voxel-cli keygen options");
  opts.add_options()("help,h", "show this help")(
      "out,o", po::value<std::string>()->required(),
      "writes OUT.key (the private key, mode 0600) and OUT.pub (for voxeld --auth-public-key)");
  po::variables_map vm;
  const int rc =
      parse_options(args, opts, nullptr, "usage: voxel-cli keygen --out NAME", vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&] {
    const std::string base = vm["out"].as<std::string>();
    const auth::KeyPair k = auth::generate_key_pair();
    write_new_file(base + ".key", std::string(auth::kPrivateKeyComment) + auth::key_to_text(k.seed),
                   0600);
    write_new_file(base + ".pub", auth::key_to_text(k.public_key), 0644);
    out << "wrote " << base << ".key (private: keep it on the backend) and " << base
        << ".pub (voxeld --auth-public-key)\n";
    return 0;
  });
}

int token_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  po::options_description opts("voxel-cli token options");
  opts.add_options()("help,h", "show this help")("key", po::value<std::string>()->required(),
                                                 "the private key file (voxel-cli keygen)")(
      "player", po::value<std::string>()->required(), "player id: 1..64 bytes")(
      "name", po::value<std::string>()->required(), "display name: 1..32 bytes")(
      "role", po::value<std::string>()->default_value("player"), "viewer, player or admin")(
      "ttl", po::value<int64_t>()->default_value(3600), "seconds until it expires (1..31536000)")(
      "edit-rate", po::value<uint32_t>()->default_value(0),
      "edit budget refill in samples/s (0: the role's default)")(
      "edit-burst", po::value<uint32_t>()->default_value(0),
      "edit budget capacity in samples (0: the role's default)");
  po::variables_map vm;
  const int rc = parse_options(
      args, opts, nullptr,
      "usage: voxel-cli token --key FILE --player ID --name NAME [--role ROLE] [--ttl SECONDS]", vm,
      out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&] {
    const auto role = auth::parse_role(vm["role"].as<std::string>());
    if (!role) throw std::invalid_argument("--role must be viewer, player or admin");
    const int64_t ttl = vm["ttl"].as<int64_t>();
    if (ttl < 1 || ttl > 31'536'000) throw std::invalid_argument("--ttl must be 1..31536000");
    const int64_t now = std::chrono::duration_cast<std::chrono::seconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count();
    const auth::PlayerClaims claims{.player_id = vm["player"].as<std::string>(),
                                    .display_name = vm["name"].as<std::string>(),
                                    .role = *role,
                                    .expires_at = now + ttl,
                                    .edit_rate = vm["edit-rate"].as<uint32_t>(),
                                    .edit_burst = vm["edit-burst"].as<uint32_t>()};
    const auth::SecretSeed seed = auth::read_private_key_file(vm["key"].as<std::string>());
    out << auth::mint_token(claims, seed) << "\n";  // invalid_argument: a claim out of range
    return 0;
  });
}

}  // namespace vox::cli
