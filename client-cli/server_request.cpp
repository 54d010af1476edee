#include "client-cli/server_request.hpp"

#include "client/voxel_client.hpp"

namespace vox::cli {

wire::Envelope server_request(const po::variables_map& vm, const wire::Envelope& request,
                              const std::function<bool(const wire::Envelope&)>& is_answer,
                              const char* what) {
  using namespace std::chrono_literals;
  using Clock = std::chrono::steady_clock;
  const ServerAccess server = server_access(vm);
  client::Client c;
  c.connect(server.host, server.port, 3s);
  c.handshake("voxel-cli", 10s, server.token);
  c.send(request);
  const auto deadline = Clock::now() + 10s;
  while (Clock::now() < deadline) {
    auto m =
        c.receive(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (!m) break;
    if (is_answer(*m)) return std::move(*m);
    if (m->has_error())
      throw std::runtime_error("server error " + wire::Error::Code_Name(m->error().code()) + ": " +
                               m->error().message());
  }
  throw std::runtime_error(std::string("no ") + what + " within 10 s");
}

}  // namespace vox::cli
