// GET /metrics from a voxeld the test started, parsed into "name{labels}" -> value; any
// other GET whole.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <boost/asio.hpp>
#include <map>
#include <sstream>
#include <string>

namespace vox::test {

// The whole response to GET `path` (HTTP/1.0: the server closes after it); empty when
// nothing listens.
inline std::string http_get(uint16_t port, const std::string& path) {
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::tcp::socket s(io);
  boost::system::error_code ec;
  s.connect({asio::ip::make_address("127.0.0.1"), port}, ec);
  if (ec) return {};
  const std::string request = "GET " + path + " HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
  asio::write(s, asio::buffer(request), ec);
  std::string response;
  std::array<char, 8192> buf;
  while (!ec) {
    const size_t n = s.read_some(asio::buffer(buf), ec);
    response.append(buf.data(), n);
  }
  return response;
}

inline std::map<std::string, double> scrape(uint16_t port) {
  const std::string response = http_get(port, "/metrics");
  std::map<std::string, double> out;
  const size_t body = response.find("\r\n\r\n");
  EXPECT_NE(body, std::string::npos);
  EXPECT_NE(response.find("200 OK"), std::string::npos) << response.substr(0, 200);
  std::istringstream lines(response.substr(body + 4));
  for (std::string line; std::getline(lines, line);) {
    if (line.empty() || line[0] == '#') continue;
    const size_t space = line.rfind(' ');
    EXPECT_NE(space, std::string::npos) << line;
    if (space == std::string::npos) continue;
    out[line.substr(0, space)] = std::stod(line.substr(space + 1));
  }
  return out;
}

}  // namespace vox::test
