// The PROXY protocol v2 header a trusted proxy sends first on the TCP port
// (server/net/proxy_header.hpp), and voxeld taking its players as the clients it names
// (docs/CLUSTER.md, "Clients": HAProxy in front of a cluster's nodes).
#include "server/net/proxy_header.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "tests/server_process.hpp"
#include "tests/session_test_util.hpp"

namespace vox {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<uint8_t>;

// A header as HAProxy's send-proxy-v2 writes it: `command` 1 (PROXY) or 0 (LOCAL).
Bytes header(const Bytes& source, uint8_t command = 1, Bytes tlvs = {}) {
  Bytes out = {0x0D, 0x0A, 0x0D, 0x0A, 0x00, 0x0D, 0x0A, 0x51, 0x55, 0x49, 0x54, 0x0A};
  out.push_back(static_cast<uint8_t>(0x20 | command));
  const bool v4 = source.size() == 4;
  out.push_back(source.empty() ? 0x00 : v4 ? 0x11 : 0x21);
  Bytes rest = source;
  rest.insert(rest.end(), source.size(), 0x7f);                            // the destination
  if (!source.empty()) rest.insert(rest.end(), {0x1f, 0x90, 0x1e, 0x61});  // ports
  rest.insert(rest.end(), tlvs.begin(), tlvs.end());
  out.push_back(static_cast<uint8_t>(rest.size() >> 8));
  out.push_back(static_cast<uint8_t>(rest.size()));
  out.insert(out.end(), rest.begin(), rest.end());
  return out;
}

std::optional<net::ProxyClient> parse(const Bytes& h, std::string& why) {
  if (h.size() < net::kProxyHeadBytes) return std::nullopt;
  const std::span<const uint8_t, net::kProxyHeadBytes> head(h.data(), net::kProxyHeadBytes);
  return net::parse_proxy_v2(head, std::span(h).subspan(net::kProxyHeadBytes), why);
}

TEST(ProxyHeader, NamesTheClientOfATcpConnectionOverIpv4OrIpv6) {
  std::string why;
  const auto v4 = parse(header({10, 1, 2, 3}, 1, {0x04, 0x00, 0x01, 0x00}), why);  // and a TLV
  ASSERT_TRUE(v4) << why;
  EXPECT_EQ(v4->address->to_string(), "10.1.2.3");
  Bytes six(16, 0);
  six[0] = 0x20, six[1] = 0x01, six[15] = 0x09;
  const auto v6 = parse(header(six), why);
  ASSERT_TRUE(v6) << why;
  EXPECT_EQ(v6->address->to_string(), "2001::9");
  // The proxy's own connection (a LOCAL command, or no address): its own address stands.
  const auto local = parse(header({10, 1, 2, 3}, 0), why);
  ASSERT_TRUE(local) << why;
  EXPECT_FALSE(local->address);
  const auto unspec = parse(header({}), why);
  ASSERT_TRUE(unspec) << why;
  EXPECT_FALSE(unspec->address);
}

TEST(ProxyHeader, AnythingElseIsRefusedWithItsReason) {
  std::string why;
  Bytes bad = header({10, 1, 2, 3});
  bad[3] = 'X';  // not the signature: a client talking straight to voxeld, say
  EXPECT_FALSE(parse(bad, why));
  EXPECT_NE(why.find("signature"), std::string::npos) << why;
  bad = header({10, 1, 2, 3});
  bad[12] = 0x11;  // version 1
  EXPECT_FALSE(parse(bad, why));
  bad = header({10, 1, 2, 3});
  bad[12] = 0x22;  // an unknown command
  EXPECT_FALSE(parse(bad, why));
  bad = header({10, 1, 2, 3});
  bad[13] = 0x12;  // UDP
  EXPECT_FALSE(parse(bad, why));
  bad = header({10, 1, 2, 3});
  bad[13] = 0x31;  // a UNIX socket
  EXPECT_FALSE(parse(bad, why));
  bad = header({10, 1, 2, 3});
  bad[15] = 4;  // too short for two IPv4 addresses and ports
  bad.resize(net::kProxyHeadBytes + 4);
  EXPECT_FALSE(parse(bad, why));
  bad = header({10, 1, 2, 3});
  bad.pop_back();  // shorter than it says
  EXPECT_FALSE(parse(bad, why));
  bad = header({10, 1, 2, 3});
  bad[14] = 0x08;  // 2,060 bytes to follow: over the bound, refused from the head alone
  const std::span<const uint8_t, net::kProxyHeadBytes> head(bad.data(), net::kProxyHeadBytes);
  EXPECT_FALSE(net::proxy_v2_rest(head, why));
  EXPECT_NE(why.find("at most"), std::string::npos) << why;
}

// voxeld behind a proxy sending the header: each player is capped by the address the proxy
// names, not by the proxy's own; a connection from the proxy without the header is closed.
TEST(ProxyHeader, PlayersBehindATrustedProxyAreCappedByTheirOwnAddresses) {
  test::ServerProcess server({"--in-memory", "--proxy-protocol-from", "127.0.0.1",
                              "--max-per-address", "1", "--max-handshaking-per-address", "1"});
  const auto through_proxy = [&](const Bytes& h, const std::string& name) {
    auto c = test::connect_to(server);
    c->send_raw(h);
    c->handshake(name, 5s * test::kSlow);
    return c;
  };
  auto first = through_proxy(header({10, 0, 0, 1}), "first");
  auto second = through_proxy(header({10, 0, 0, 2}), "second");  // another client: admitted
  // The same client again: its address is full (one connection each here).
  EXPECT_THROW(through_proxy(header({10, 0, 0, 1}), "again"), std::runtime_error);
  // The proxy's own connection counts as the proxy's address.
  auto local = through_proxy(header({10, 0, 0, 1}, 0), "local");
  // No header: closed without a Welcome.
  auto bare = test::connect_to(server);
  EXPECT_THROW(bare->handshake("bare", 5s * test::kSlow), std::runtime_error);
}

}  // namespace
}  // namespace vox
