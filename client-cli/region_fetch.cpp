#include "client-cli/region_fetch.hpp"

#include "client-cli/cli_options.hpp"

namespace vox::cli {

using namespace std::chrono_literals;

std::unique_ptr<client::Client> fetch_region(const ServerAccess& server, const std::string& name,
                                             const std::array<float, 3>& at, uint32_t radius,
                                             std::chrono::milliseconds timeout, uint32_t lod_level,
                                             float lod_distance) {
  auto c = std::make_unique<client::Client>();
  c->connect(server.host, server.port, 3s);
  c->handshake(name, 10s, server.token);
  constexpr uint64_t kViewId = 1;
  c->send(client::make_set_view(at[0], at[1], at[2], radius, kViewId, lod_level, lod_distance));
  c->receive_view(kViewId, timeout);
  bool any = !c->chunks().empty();
  for (uint32_t level = 1; level <= lod_level; ++level) any = any || !c->lod_chunks(level).empty();
  if (!any) throw std::runtime_error("no surface around that point");
  return c;
}

}  // namespace vox::cli
