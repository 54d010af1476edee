// GET /metrics from a voxeld the test started, parsed into "name{labels}" -> value.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <boost/asio.hpp>
#include <map>
#include <sstream>
#include <string>

namespace vox::test {

inline std::map<std::string, double> scrape(uint16_t port) {
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::tcp::socket s(io);
  s.connect({asio::ip::make_address("127.0.0.1"), port});
  const std::string request = "GET /metrics HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
  asio::write(s, asio::buffer(request));
  std::string response;
  boost::system::error_code ec;
  std::array<char, 8192> buf;
  for (;;) {
    const size_t n = s.read_some(asio::buffer(buf), ec);
    response.append(buf.data(), n);
    if (ec) break;
  }
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
