#include "client-cli/region_fetch.hpp"

#include "client-cli/cli_options.hpp"

namespace vox::cli {

using namespace std::chrono_literals;

std::unique_ptr<client::Client> fetch_region(const std::string& server, const std::string& name,
                                             const std::array<float, 3>& at, uint32_t radius,
                                             std::chrono::milliseconds quiet) {
  const auto [host, port] = parse_server(server);
  auto c = std::make_unique<client::Client>();
  c->connect(host, port, 3s);
  c->handshake(name, 10s);
  c->send(client::make_set_view(at[0], at[1], at[2], radius));
  const auto deadline = client::Clock::now() + 120s;
  for (bool first = true; client::Clock::now() < deadline; first = false) {
    auto m = c->receive(first ? std::chrono::milliseconds(30s) : quiet);
    if (!m) break;
    if (m->has_error()) throw std::runtime_error("server error: " + m->error().message());
    if (m->has_chunk_mesh()) {
      if (auto error = c->apply(m->chunk_mesh())) throw std::runtime_error("bad mesh from the server: " + *error);
    }
  }
  if (c->chunks().empty()) throw std::runtime_error("no surface around that point (or no reply from the server)");
  return c;
}

}  // namespace vox::cli
