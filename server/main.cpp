// voxeld: flags, logging, signals; the server itself lives in the voxel_net library.
#include <spdlog/spdlog.h>

#include <utility>
#include <boost/asio.hpp>
#include <boost/program_options.hpp>
#include <fstream>
#include <iostream>
#include <thread>

#include "net/server.hpp"

namespace po = boost::program_options;
namespace asio = boost::asio;

int main(int argc, char** argv) {
  vox::net::ServerConfig net;
  vox::pipeline::PipelineConfig world;
  std::string port_file, log_level;
  int io_threads = 1, stats_seconds = 10;
  long idle_ms = 60000, handshake_ms = 5000, write_ms = 10000;
  po::options_description opts("voxeld options");
  opts.add_options()("help,h", "show this help")(
      "port", po::value<uint16_t>(&net.port)->default_value(7777), "TCP port (0: pick a free one)")(
      "bind", po::value<std::string>(&net.bind)->default_value("127.0.0.1"), "address to listen on")(
      "port-file", po::value<std::string>(&port_file), "write the bound port to this file")(
      "seed", po::value<uint64_t>(&world.seed)->default_value(1), "world seed")(
      "threads", po::value<int>(&world.threads)->default_value(0), "world pipeline threads (0: all cores)")(
      "io-threads", po::value<int>(&io_threads)->default_value(1), "network threads")(
      "max-clients", po::value<size_t>(&net.max_clients)->default_value(256), "connections beyond this are refused")(
      "max-view-radius", po::value<uint32_t>(&net.max_view_radius)->default_value(12), "largest view radius in chunks")(
      "idle-timeout-ms", po::value<long>(&idle_ms)->default_value(60000), "disconnect clients silent this long")(
      "handshake-timeout-ms", po::value<long>(&handshake_ms)->default_value(5000), "time allowed for Hello")(
      "write-timeout-ms", po::value<long>(&write_ms)->default_value(10000), "disconnect clients that stop reading")(
      "stats-interval", po::value<int>(&stats_seconds)->default_value(10), "seconds between stats lines (0: none)")(
      "log-level", po::value<std::string>(&log_level)->default_value("info"), "trace, debug, info, warn, error");
  po::variables_map vm;
  try {
    po::store(po::parse_command_line(argc, argv, opts), vm);
    if (vm.count("help")) {
      std::cout << "usage: voxeld [options]\n" << opts;
      return 0;
    }
    po::notify(vm);
  } catch (const po::error& e) {
    std::cerr << "voxeld: " << e.what() << " (see --help)\n";
    return 2;
  }
  // The view radius bounds each session's memory (a ball of radius r holds ~4.2 r^3 chunks).
  if (io_threads < 1 || io_threads > 64 || world.threads < 0 || idle_ms <= 0 || handshake_ms <= 0 || write_ms <= 0 ||
      net.max_view_radius > 32 || net.max_clients < 1) {
    std::cerr << "voxeld: --io-threads must be 1..64, --threads >= 0, --max-view-radius <= 32, --max-clients >= 1, "
                 "timeouts > 0\n";
    return 2;
  }
  spdlog::set_level(spdlog::level::from_str(log_level));
  net.idle_timeout = std::chrono::milliseconds(idle_ms);
  net.handshake_timeout = std::chrono::milliseconds(handshake_ms);
  net.write_timeout = std::chrono::milliseconds(write_ms);

  try {
    vox::pipeline::WorldPipeline pipeline(world);
    asio::io_context io;
    vox::net::Server server(io, net, pipeline);
    server.start();
    if (!port_file.empty()) {
      const std::string tmp = port_file + ".tmp";
      std::ofstream(tmp) << server.port() << "\n";
      std::rename(tmp.c_str(), port_file.c_str());
    }
    if (stats_seconds > 0) server.start_stats_log(std::chrono::seconds(stats_seconds));
    asio::signal_set signals(io, SIGINT, SIGTERM);
    signals.async_wait([&](boost::system::error_code ec, int signal) {
      if (ec) return;
      spdlog::info("signal {}: shutting down", signal);
      server.stop();
      // Finish the batch in flight, then let the sessions flush their SHUTTING_DOWN.
      pipeline.stop();
      auto deadline = std::make_shared<asio::steady_timer>(io, std::chrono::seconds(2));
      deadline->async_wait([&io, deadline](boost::system::error_code) { io.stop(); });
    });
    std::vector<std::thread> threads;
    for (int i = 1; i < io_threads; ++i) threads.emplace_back([&io] { io.run(); });
    io.run();
    for (auto& t : threads) t.join();
    spdlog::info("voxeld stopped");
  } catch (const std::exception& e) {
    spdlog::error("voxeld: {}", e.what());
    return 1;
  }
  return 0;
}
