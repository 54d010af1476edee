// voxel-cli's network commands: info, one command per edit type, script, watch.
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "client-cli/cli_options.hpp"
#include "client-cli/commands.hpp"
#include "client/voxel_client.hpp"

namespace vox::cli {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr auto kConnectTimeout = 3s;
constexpr auto kReplyTimeout = 10s;

std::unique_ptr<client::Client> open_session(const ServerAccess& server, const std::string& name) {
  auto c = std::make_unique<client::Client>();
  c->connect(server.host, server.port, kConnectTimeout);
  c->handshake(name, kReplyTimeout, server.token);
  return c;
}

void set_vec3(wire::Vec3* v, const std::array<float, 3>& a) {
  v->set_x(a[0]);
  v->set_y(a[1]);
  v->set_z(a[2]);
}

po::options_description edit_options(const std::string& kind) {
  po::options_description o = network_options(kind);
  if (kind == "stamp") {
    o.add_options()("shape", po::value<std::string>()->default_value("box"), "box or sphere")(
        "min", po::value<std::string>(), "X,Y,Z: box corner")("max", po::value<std::string>(),
                                                              "X,Y,Z: box corner")(
        "at", po::value<std::string>(), "X,Y,Z: sphere centre")("radius", po::value<float>(),
                                                                "sphere radius")(
        "air", po::bool_switch(), "carve the shape to air instead of filling it")(
        "material", po::value<uint32_t>()->default_value(3), "1..255");
    return o;
  }
  o.add_options()("at", po::value<std::string>()->required(), "X,Y,Z: centre in world voxels")(
      "radius", po::value<float>()->required(), "radius in voxels");
  if (kind == "brush") {
    o.add_options()("strength", po::value<float>()->default_value(0.5f),
                    "density added per sample at the centre")("remove", po::bool_switch(),
                                                              "take material away")(
        "material", po::value<uint32_t>()->default_value(0),
        "material where it adds (0: keep / dirt)");
  } else if (kind == "explode") {
    o.add_options()("power", po::value<float>()->default_value(1.0f),
                    "density removed at the centre");
  } else if (kind == "smooth") {
    o.add_options()("strength", po::value<float>()->default_value(0.5f), "0 < strength <= 1");
  } else if (kind == "paint") {
    o.add_options()("material", po::value<uint32_t>()->required(), "1..255");
  }
  return o;
}

// The Edit message for an edit command's options (values are checked by the server).
wire::Envelope edit_from_options(const std::string& kind, const po::variables_map& vm,
                                 uint64_t request) {
  wire::Envelope m;
  wire::Edit* e = m.mutable_edit();
  e->set_request_id(request);
  if (kind == "brush") {
    auto* b = e->mutable_brush();
    set_vec3(b->mutable_center(), parse_vec3(vm["at"].as<std::string>(), "--at"));
    b->set_radius(vm["radius"].as<float>());
    b->set_strength(vm["strength"].as<float>());
    b->set_remove(vm["remove"].as<bool>());
    b->set_material(vm["material"].as<uint32_t>());
  } else if (kind == "explode") {
    auto* x = e->mutable_explosion();
    set_vec3(x->mutable_center(), parse_vec3(vm["at"].as<std::string>(), "--at"));
    x->set_radius(vm["radius"].as<float>());
    x->set_power(vm["power"].as<float>());
  } else if (kind == "smooth") {
    auto* s = e->mutable_smooth();
    set_vec3(s->mutable_center(), parse_vec3(vm["at"].as<std::string>(), "--at"));
    s->set_radius(vm["radius"].as<float>());
    s->set_strength(vm["strength"].as<float>());
  } else if (kind == "paint") {
    auto* p = e->mutable_paint();
    set_vec3(p->mutable_center(), parse_vec3(vm["at"].as<std::string>(), "--at"));
    p->set_radius(vm["radius"].as<float>());
    p->set_material(vm["material"].as<uint32_t>());
  } else {
    auto* s = e->mutable_stamp();
    const std::string shape = vm["shape"].as<std::string>();
    if (shape == "sphere") {
      if (!vm.count("at") || !vm.count("radius"))
        throw std::invalid_argument("a sphere stamp needs --at and --radius");
      s->set_shape(wire::Stamp::SPHERE);
      set_vec3(s->mutable_center(), parse_vec3(vm["at"].as<std::string>(), "--at"));
      s->set_radius(vm["radius"].as<float>());
    } else if (shape == "box") {
      if (!vm.count("min") || !vm.count("max"))
        throw std::invalid_argument("a box stamp needs --min and --max");
      s->set_shape(wire::Stamp::BOX);
      set_vec3(s->mutable_min(), parse_vec3(vm["min"].as<std::string>(), "--min"));
      set_vec3(s->mutable_max(), parse_vec3(vm["max"].as<std::string>(), "--max"));
    } else {
      throw std::invalid_argument("--shape must be box or sphere, got '" + shape + "'");
    }
    s->set_solid(!vm["air"].as<bool>());
    s->set_material(vm["material"].as<uint32_t>());
  }
  return m;
}

// Waits for the EditResult of `request` (meshes on the way are ignored).
std::optional<wire::EditResult> wait_result(client::Client& c, uint64_t request) {
  const auto deadline = Clock::now() + kReplyTimeout;
  while (Clock::now() < deadline) {
    auto m =
        c.receive(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (!m) return std::nullopt;
    if (m->has_edit_result() && m->edit_result().request_id() == request) return m->edit_result();
    if (m->has_error())
      throw std::runtime_error("server error " + wire::Error::Code_Name(m->error().code()) + ": " +
                               m->error().message());
  }
  return std::nullopt;
}

std::string describe(const wire::EditResult& r) {
  std::ostringstream s;
  if (r.status() != wire::EditResult::ACCEPTED) {
    s << "refused: " << wire::EditResult::Status_Name(r.status()) << ": " << r.reason();
    return s.str();
  }
  s << "accepted: " << r.changed_chunks_size() << " chunk mesh"
    << (r.changed_chunks_size() == 1 ? "" : "es") << " changed";
  for (const auto& c : r.changed_chunks())
    s << " (" << c.x() << "," << c.y() << "," << c.z() << ")";
  if (r.clipped_by_size() > 0) {
    s << "; clipped: protected region" << (r.clipped_by_size() == 1 ? "" : "s");
    for (const uint64_t id : r.clipped_by()) s << " " << id;
    s << " kept as it was";
  }
  for (const wire::MaterialVolume& v : r.volumes()) {
    char line[96];
    std::snprintf(line, sizeof line, "; material %u: %.2f removed, %.2f added", v.material(),
                  v.removed(), v.added());
    s << line;
  }
  if (r.volumes_size() == 0)
    s << " (nothing there to change: 'voxel-cli ground --at X,Z' finds the surface)";
  return s.str();
}

std::atomic<bool> g_interrupted{false};
extern "C" void on_sigint(int) { g_interrupted = true; }

}  // namespace

int info_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  po::options_description opts = network_options("info");
  po::variables_map vm;
  const int rc = parse_options(args, opts, nullptr, "usage: voxel-cli info [--server HOST:PORT]",
                               vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&] {
    const ServerAccess server = server_access(vm);
    client::Client c;
    c.connect(server.host, server.port, kConnectTimeout);
    const wire::Welcome w = c.handshake("voxel-cli", kReplyTimeout, server.token);
    out << "server:          " << w.server_version() << "\n"
        << "protocol:        " << w.protocol_version() << " (mesh format " << w.mesh_format()
        << ")\n"
        << "world seed:      " << w.world_seed() << "\n"
        << "chunk size:      " << w.chunk_size() << "\n"
        << "players:         " << w.players() << "\n"
        << "max view radius: " << w.max_view_radius() << " chunks\n"
        << "max edit radius: " << w.max_edit_radius() << "\n"
        << "max strength:    " << w.max_edit_strength() << "\n"
        << "max frame:       " << w.max_frame_bytes() << " bytes\n";
    return 0;
  });
}

int edit_command(const std::string& kind, const std::vector<std::string>& args, std::ostream& out,
                 std::ostream& err) {
  const po::options_description opts = edit_options(kind);
  po::variables_map vm;
  const std::string synopsis = "usage: voxel-cli " + kind + " [options]";
  const int rc = parse_options(args, opts, nullptr, synopsis.c_str(), vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&] {
    const wire::Envelope edit = edit_from_options(kind, vm, 1);
    auto c = open_session(server_access(vm), "voxel-cli");
    const auto t0 = Clock::now();
    c->send(edit);
    const auto result = wait_result(*c, 1);
    if (!result)
      throw std::runtime_error("no EditResult within " + std::to_string(kReplyTimeout.count()) +
                               " s");
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    if (result->status() != wire::EditResult::ACCEPTED) {
      err << "voxel-cli: " << describe(*result) << "\n";
      return 1;
    }
    out << describe(*result) << " in " << std::fixed << std::setprecision(2) << ms << " ms\n";
    return 0;
  });
}

int script_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  po::options_description opts = network_options("script");
  opts.add_options()("file", po::value<std::string>()->required(), "edits, one per line")(
      "window", po::value<int>()->default_value(32), "edits in flight at once (1..1024)");
  po::positional_options_description positional;
  positional.add("file", 1);
  po::variables_map vm;
  const int rc = parse_options(args, opts, &positional,
                               "usage: voxel-cli script FILE [--server HOST:PORT]", vm, out, err);
  if (rc >= 0) return rc;
  const int window = vm["window"].as<int>();
  if (window < 1 || window > 1024) {
    err << "voxel-cli: --window must be 1..1024\n";
    return 2;
  }
  // Parse every line first: a bad script sends nothing.
  std::ifstream in(vm["file"].as<std::string>());
  if (!in) {
    err << "voxel-cli: error: cannot open " << vm["file"].as<std::string>() << "\n";
    return 1;
  }
  std::vector<wire::Envelope> edits;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    std::istringstream words(line);
    std::vector<std::string> tokens;
    for (std::string w; words >> w;) tokens.push_back(w);
    if (tokens.empty() || tokens[0][0] == '#') continue;
    const std::string kind = tokens[0];
    if (kind != "brush" && kind != "explode" && kind != "smooth" && kind != "paint" &&
        kind != "stamp") {
      err << "voxel-cli: line " << number << ": unknown edit '" << kind << "'\n";
      return 2;
    }
    try {
      po::variables_map line_vm;
      po::store(po::command_line_parser(std::vector<std::string>(tokens.begin() + 1, tokens.end()))
                    .options(edit_options(kind))
                    .run(),
                line_vm);
      po::notify(line_vm);
      edits.push_back(edit_from_options(kind, line_vm, edits.size() + 1));
    } catch (const std::exception& e) {
      err << "voxel-cli: line " << number << ": " << e.what() << "\n";
      return 2;
    }
  }
  return guarded(err, [&] {
    auto c = open_session(server_access(vm), "voxel-cli-script");
    const auto t0 = Clock::now();
    size_t sent = 0, done = 0, refused = 0;
    while (done < edits.size()) {
      while (sent < edits.size() && sent - done < static_cast<size_t>(window))
        c->send(edits[sent++]);
      auto m = c->receive(kReplyTimeout);
      if (!m)
        throw std::runtime_error(c->closed() ? "the server closed the connection"
                                             : "no reply in time");
      if (m->has_error()) throw std::runtime_error("server error: " + m->error().message());
      if (!m->has_edit_result()) continue;
      ++done;
      if (m->edit_result().status() != wire::EditResult::ACCEPTED) {
        ++refused;
        err << "voxel-cli: edit " << m->edit_result().request_id() << " "
            << describe(m->edit_result()) << "\n";
      }
    }
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    out << edits.size() << " edits (" << refused << " refused) in " << std::fixed
        << std::setprecision(3) << s << " s: " << std::setprecision(0)
        << static_cast<double>(edits.size()) / std::max(s, 1e-9) << " edits/s\n";
    return refused == 0 ? 0 : 1;
  });
}

int watch_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  po::options_description opts = network_options("watch");
  add_view_options(opts, "X,Y,Z: view centre", false);
  opts.add_options()("for", po::value<double>(),
                     "stop after this many seconds (default: until Ctrl-C)");
  po::variables_map vm;
  const int rc =
      parse_options(args, opts, nullptr,
                    "usage: voxel-cli watch --at X,Y,Z --radius N [--for SECONDS]", vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&] {
    const auto at = parse_vec3(vm["at"].as<std::string>(), "--at");
    const double seconds = vm.count("for") ? vm["for"].as<double>() : 1e12;
    if (!(seconds > 0)) throw std::invalid_argument("--for must be > 0");
    auto c = open_session(server_access(vm), "voxel-cli-watch");
    c->send(client::make_set_view(at[0], at[1], at[2], vm["radius"].as<uint32_t>(), 1));
    g_interrupted = false;
    auto previous = std::signal(SIGINT, on_sigint);
    const auto t0 = Clock::now();
    auto last_ping = t0;
    size_t updates = 0, fulls = 0, deltas = 0, bytes = 0, failures = 0;
    while (!g_interrupted && std::chrono::duration<double>(Clock::now() - t0).count() < seconds) {
      if (Clock::now() - last_ping > 10s) {  // keep the session alive
        wire::Envelope ping;
        ping.mutable_ping()->set_nonce(1);
        c->send(ping);
        last_ping = Clock::now();
      }
      auto m = c->receive(200ms);
      if (!m) {
        if (c->closed()) throw std::runtime_error("the server closed the connection");
        continue;
      }
      if (m->has_error()) throw std::runtime_error("server error: " + m->error().message());
      if (m->has_chunk_unload()) {
        c->forget(m->chunk_unload());
        out << "unload " << m->chunk_unload().coords_size() << " chunks\n";
      }
      if (m->has_view_ready()) {
        const auto& r = m->view_ready();
        out << "view ready: " << r.chunks_sent() << " chunks with a surface, " << r.chunks_empty()
            << " empty, after " << std::fixed << std::setprecision(2)
            << std::chrono::duration<double>(Clock::now() - t0).count() << " s\n";
      }
      if (!m->has_chunk_mesh()) continue;
      const auto& k = m->chunk_mesh().coord();
      const bool delta = m->chunk_mesh().base_version() != 0;
      const auto error = c->apply(m->chunk_mesh());
      ++updates;
      (delta ? deltas : fulls) += 1;
      bytes += m->chunk_mesh().payload().size();
      out << "chunk (" << k.x() << "," << k.y() << "," << k.z() << ") v"
          << m->chunk_mesh().version() << " "
          << (delta ? "delta from v" + std::to_string(m->chunk_mesh().base_version())
                    : std::string("full"))
          << " " << m->chunk_mesh().payload().size() << " bytes"
          << (error ? " DECODE FAILED: " + *error : "") << "\n";
      if (error) {  // the documented recovery: ask for a full copy
        ++failures;
        c->send(client::make_resync({&k, 1}));
      }
    }
    std::signal(SIGINT, previous);
    out << "watched " << std::fixed << std::setprecision(1)
        << std::chrono::duration<double>(Clock::now() - t0).count() << " s: " << updates
        << " updates (" << fulls << " full, " << deltas << " delta), " << bytes << " bytes, "
        << c->chunks().size() << " chunks held\n";
    return failures == 0 ? 0 : 1;
  });
}

}  // namespace vox::cli
