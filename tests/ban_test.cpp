// Players, kicks and bans (docs/PROTOCOL.md 4.11). The BanBook's rules; then a real voxeld
// with tokens: an admin lists the players, kicks one, bans one (closed BANNED at once,
// refused at Hello with the reason and the end, still after a restart) and unbans it; a
// player may do none of it; an address ban ends on time; a ban written to the world by
// another process takes effect on SIGHUP. voxel-cli's commands drive the same messages.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "client-cli/commands.hpp"
#include "client/voxel_client.hpp"
#include "server/auth/player_token.hpp"
#include "server/net/address_key.hpp"
#include "server/net/ban_book.hpp"
#include "server/net/ban_keeper.hpp"
#include "server/store/ban_store.hpp"
#include "server/store/world_store.hpp"
#include "tests/server_process.hpp"
#include "tests/temp_dir.hpp"
#include "tests/token_world.hpp"

namespace vox {
namespace {

using namespace std::chrono_literals;
using client::Client;
using store::Ban;

Ban ban(Ban::Kind kind, const std::string& target, int64_t until_ms = 0) {
  Ban b;
  b.kind = kind;
  b.target = target;
  b.until_ms = until_ms;
  return b;
}

TEST(BanBook, APlayersBanComesBeforeItsAddressesAndAnEndedBanHoldsNobody) {
  net::BanBook book;
  EXPECT_TRUE(book.put(ban(Ban::Kind::kAddress, "10.0.0.1", 500)));
  EXPECT_FALSE(book.match("alice", "10.0.0.2", 0));
  ASSERT_TRUE(book.match("alice", "10.0.0.1", 0));
  EXPECT_EQ(book.match("alice", "10.0.0.1", 0)->kind, Ban::Kind::kAddress);
  EXPECT_FALSE(book.match("alice", "10.0.0.1", 500));  // ended
  EXPECT_TRUE(book.put(ban(Ban::Kind::kPlayer, "alice")));
  EXPECT_EQ(book.match("alice", "10.0.0.1", 0)->kind, Ban::Kind::kPlayer);
  EXPECT_FALSE(book.match("", "10.0.0.9", 0));  // no id: the address only
  EXPECT_EQ(book.remove(Ban::Kind::kPlayer, "alice")->target, "alice");
  EXPECT_FALSE(book.remove(Ban::Kind::kPlayer, "alice"));
  book.drop_ended(1000);
  EXPECT_EQ(book.size(), 0u);
}

TEST(BanBook, AReplacementTellsWhichBansAreNew) {
  net::BanBook book;
  book.put(ban(Ban::Kind::kPlayer, "a"));
  book.put(ban(Ban::Kind::kPlayer, "b", 100));
  const auto added = book.replace({ban(Ban::Kind::kPlayer, "a"), ban(Ban::Kind::kPlayer, "b"),
                                   ban(Ban::Kind::kPlayer, "c"), ban(Ban::Kind::kPlayer, "d", 50)},
                                  200);
  // b's old ban had ended at 100: it is new again; d's ends before now.
  ASSERT_EQ(added.size(), 2u);
  EXPECT_EQ(added[0].target, "b");
  EXPECT_EQ(added[1].target, "c");
  EXPECT_EQ(book.size(), 3u);
}

TEST(BanBook, PagesFollowTheirCursorsAndTheBookHasABound) {
  net::BanBook book;
  for (int i = 0; i < 250; ++i) {
    std::string id = "p";  // (+= : GCC 12 sees a false overlap in "p" + to_string)
    id += std::to_string(1000 + i);
    book.put(ban(Ban::Kind::kPlayer, id));
  }
  book.put(ban(Ban::Kind::kAddress, "10.0.0.1"));
  std::string cursor;
  size_t seen = 0, pages = 0;
  do {
    const net::BanBook::Page page = book.page(cursor, 100, 0);
    seen += page.bans.size();
    ++pages;
    cursor = page.next;
  } while (!cursor.empty());
  EXPECT_EQ(seen, 251u);
  EXPECT_EQ(pages, 3u);
  EXPECT_TRUE(book.page("not a cursor", 10, 0).bans.size() <= 10);  // no throw, a page
  for (size_t i = book.size(); i < store::kMaxBans; ++i)
    ASSERT_TRUE(book.put(ban(Ban::Kind::kAddress, std::to_string(i))));
  EXPECT_FALSE(book.put(ban(Ban::Kind::kPlayer, "one more")));
  EXPECT_TRUE(book.put(ban(Ban::Kind::kPlayer, "p1000", 7)));  // a replacement still goes
  EXPECT_EQ(book.size(), store::kMaxBans);
}

TEST(BanTargets, AnAddressInAnyOfItsFormsIsTheKeyAdmissionCountsBy) {
  EXPECT_EQ(net::address_key_of("203.0.113.7"), "203.0.113.7");
  EXPECT_EQ(net::address_key_of("::ffff:203.0.113.7"), "203.0.113.7");
  EXPECT_EQ(net::address_key_of("2001:db8::5"), "2001:db8::/64");
  EXPECT_EQ(net::address_key_of("2001:db8::/64"), "2001:db8::/64");  // as `bans` prints it
  EXPECT_FALSE(net::address_key_of("203.0.113.7/64"));
  EXPECT_FALSE(net::address_key_of("::ffff:203.0.113.7/64"));
  EXPECT_FALSE(net::address_key_of("mallory"));
  EXPECT_FALSE(net::address_key_of(""));
  EXPECT_FALSE(net::address_key_of(std::string(100, '1')));
}

TEST(BanKeeper, RowsWrittenByOtherToolsAreReadInTheFormAdmissionMatches) {
  test::TempDir dir("bans");
  const std::string where = (dir / "world").string();
  store::open_world_store(where, {});
  auto other = store::open_ban_store(where);
  other->put(ban(Ban::Kind::kAddress, "::ffff:10.0.0.1"));
  other->put(ban(Ban::Kind::kAddress, "2001:db8::77"));
  other->put(ban(Ban::Kind::kAddress, "not an address"));
  net::BanKeeper keeper(store::open_ban_store(where));
  EXPECT_TRUE(keeper.match("", "10.0.0.1"));
  EXPECT_TRUE(keeper.match("", "2001:db8::/64"));
  EXPECT_EQ(keeper.size(), 2u);
}

class Bans : public test::TokenWorld {
 protected:
  Bans() : TokenWorld("bans") {}
  std::vector<std::string> server_args() const { return key_and_world(); }
  // The Error a connection is closed with (skipping what came before).
  static wire::Error closed_with(Client& c) {
    for (;;) {
      auto m = c.receive(10s);
      if (!m) return {};
      if (m->has_error()) return m->error();
    }
  }
  static wire::AdminResult ask(Client& c, wire::Envelope m) {
    m.mutable_admin_command()->set_request_id(42);
    c.send(m);
    for (;;) {
      auto r = c.receive(10s);
      if (!r) return {};
      if (r->has_admin_result()) return r->admin_result();
    }
  }
};

TEST_F(Bans, OnlyAnAdminListsKicksAndBansAndABanHoldsAcrossARestartUntilUnbanned) {
  {
    test::ServerProcess server(server_args());
    auto admin = join(server.port(), token("root", auth::Role::kAdmin));
    auto alice = join(server.port(), token("alice"));
    auto mallory = join(server.port(), token("mallory"));

    wire::Envelope players;
    players.mutable_admin_command()->mutable_players();
    EXPECT_EQ(ask(*mallory, players).status(), wire::AdminResult::FORBIDDEN);
    const wire::AdminResult list = ask(*admin, players);
    ASSERT_EQ(list.status(), wire::AdminResult::OK);
    ASSERT_EQ(list.players_size(), 3);
    EXPECT_EQ(list.players(1).player_id(), "alice");
    EXPECT_EQ(list.players(1).name(), "Name of alice");
    EXPECT_EQ(list.players(1).role(), "player");
    EXPECT_EQ(list.players(1).address(), "127.0.0.1");
    EXPECT_GT(list.players(1).connected_unix_ms(), 0);
    EXPECT_FALSE(list.more());

    wire::Envelope kick;
    kick.mutable_admin_command()->mutable_kick()->set_player_id("alice");
    kick.mutable_admin_command()->mutable_kick()->set_reason("take a break");
    EXPECT_EQ(ask(*mallory, kick).status(), wire::AdminResult::FORBIDDEN);
    const wire::AdminResult kicked = ask(*admin, kick);
    EXPECT_EQ(kicked.status(), wire::AdminResult::OK);
    EXPECT_EQ(kicked.kicked(), 1u);
    const wire::Error told = closed_with(*alice);
    EXPECT_EQ(told.code(), wire::Error::KICKED);
    EXPECT_NE(told.message().find("take a break"), std::string::npos) << told.message();
    EXPECT_EQ(ask(*admin, kick).status(), wire::AdminResult::NOT_FOUND);  // gone now
    wire::Envelope self_kick;
    self_kick.mutable_admin_command()->mutable_kick()->set_player_id("root");
    EXPECT_EQ(ask(*admin, self_kick).status(), wire::AdminResult::BAD_VALUE);
    self_kick.mutable_admin_command()->mutable_kick()->set_reason(std::string(201, 'x'));
    const wire::AdminResult long_reason = ask(*admin, self_kick);
    EXPECT_NE(long_reason.reason().find("a kick's reason is at most 200"), std::string::npos)
        << long_reason.reason();
    join(server.port(), token("alice"));  // a kick is no ban

    wire::Envelope b;
    b.mutable_admin_command()->mutable_ban()->set_player_id("mallory");
    b.mutable_admin_command()->mutable_ban()->set_reason("griefing spawn");
    const wire::AdminResult banned = ask(*admin, b);
    ASSERT_EQ(banned.status(), wire::AdminResult::OK) << banned.reason();
    EXPECT_EQ(banned.kicked(), 1u);
    ASSERT_EQ(banned.bans_size(), 1);
    EXPECT_EQ(banned.bans(0).created_by(), "root");
    EXPECT_EQ(banned.bans(0).until_unix_ms(), 0);
    EXPECT_EQ(closed_with(*mallory).code(), wire::Error::BANNED);
    EXPECT_EQ(server.terminate(), 0);
  }
  test::ServerProcess server(server_args());
  Client again;
  again.connect("127.0.0.1", server.port(), 5s);
  const wire::Envelope refused = hello(again, token("mallory"));
  ASSERT_TRUE(refused.has_error());
  EXPECT_EQ(refused.error().code(), wire::Error::BANNED);
  EXPECT_NE(refused.error().message().find("griefing spawn"), std::string::npos);
  EXPECT_EQ(refused.error().banned_until_unix_ms(), 0);

  std::string out;
  const std::string root = token("root", auth::Role::kAdmin);
  EXPECT_EQ(cli({"bans"}, server.port(), root, &out), 0) << out;
  EXPECT_NE(out.find("player mallory  forever  by root"), std::string::npos) << out;
  EXPECT_NE(out.find("1 ban in force"), std::string::npos) << out;
  EXPECT_EQ(cli({"unban", "mallory"}, server.port(), token("alice"), &out), 1);
  EXPECT_NE(out.find("FORBIDDEN"), std::string::npos) << out;
  EXPECT_EQ(cli({"unban", "mallory"}, server.port(), root, &out), 0) << out;
  EXPECT_EQ(cli({"unban", "mallory"}, server.port(), root, &out), 1) << out;
  EXPECT_NE(out.find("NOT_FOUND"), std::string::npos) << out;
  auto back = join(server.port(), token("mallory"));
  EXPECT_EQ(cli({"players"}, server.port(), root, &out), 0) << out;
  EXPECT_NE(out.find("mallory  'Name of mallory'  player  127.0.0.1"), std::string::npos) << out;
}

TEST_F(Bans, AnAddressBanKeepsEveryoneFromItOutUntilItEnds) {
  test::ServerProcess server(server_args());
  auto admin = join(server.port(), token("root", auth::Role::kAdmin));
  auto alice = join(server.port(), token("alice"));
  std::string out;
  EXPECT_EQ(cli({"ban", "127.0.0.1", "--for", "bad"}, server.port(),
                token("root", auth::Role::kAdmin), &out),
            2);  // bad usage
  EXPECT_NE(out.find("is not a duration"), std::string::npos) << out;
  wire::Envelope b;
  b.mutable_admin_command()->mutable_ban()->set_address("not an address");
  EXPECT_EQ(ask(*admin, b).status(), wire::AdminResult::BAD_VALUE);
  b.mutable_admin_command()->mutable_ban()->set_address("127.0.0.1");
  b.mutable_admin_command()->mutable_ban()->set_player_id("alice");
  EXPECT_EQ(ask(*admin, b).status(), wire::AdminResult::BAD_VALUE);  // both named
  b.mutable_admin_command()->mutable_ban()->clear_player_id();
  b.mutable_admin_command()->mutable_ban()->set_duration_seconds(2);
  const wire::AdminResult banned = ask(*admin, b);
  ASSERT_EQ(banned.status(), wire::AdminResult::OK) << banned.reason();
  EXPECT_EQ(banned.kicked(), 1u);  // alice; never the admin's own connection
  EXPECT_EQ(closed_with(*alice).code(), wire::Error::BANNED);
  Client during;
  during.connect("127.0.0.1", server.port(), 5s);
  const wire::Envelope refused = hello(during, token("bob"));
  ASSERT_TRUE(refused.has_error());
  EXPECT_EQ(refused.error().code(), wire::Error::BANNED);
  EXPECT_GT(refused.error().banned_until_unix_ms(), 0);
  EXPECT_NE(refused.error().message().find(" until "), std::string::npos);
  std::this_thread::sleep_for(std::chrono::milliseconds(2100));
  join(server.port(), token("bob"));
  wire::Envelope unban;
  unban.mutable_admin_command()->mutable_unban()->set_address("127.0.0.1");
  EXPECT_EQ(ask(*admin, unban).status(), wire::AdminResult::NOT_FOUND);  // it had ended
}

TEST_F(Bans, AnAdminIsNotHeldByAnAddressBanAndMayNotBanItself) {
  test::ServerProcess server(server_args());
  const std::string root = token("root", auth::Role::kAdmin);
  auto admin = join(server.port(), root);
  auto other_admin = join(server.port(), token("ops", auth::Role::kAdmin));
  std::string out;
  EXPECT_EQ(cli({"ban", "root"}, server.port(), root, &out), 1);
  EXPECT_NE(out.find("may not ban its own player"), std::string::npos) << out;
  // The address every connection here shares, banned by another process: refused to
  // players, never to an admin (an admin can always come back and lift it).
  store::open_ban_store((dir_ / "world").string())->put(ban(Ban::Kind::kAddress, "127.0.0.1"));
  ::kill(server.pid(), SIGHUP);
  bool refused = false;
  for (int i = 0; i < 100 && !refused; ++i) {  // until the SIGHUP's read is in force
    Client player;
    player.connect("127.0.0.1", server.port(), 5s);
    const wire::Envelope answer = hello(player, token("alice"));
    refused = answer.has_error();
    if (refused) {
      EXPECT_EQ(answer.error().code(), wire::Error::BANNED);
    }
    if (!refused) std::this_thread::sleep_for(50ms);
  }
  EXPECT_TRUE(refused);
  EXPECT_EQ(cli({"bans"}, server.port(), root, &out), 0) << out;  // an admin still gets in
  EXPECT_NE(out.find("address 127.0.0.1  forever"), std::string::npos) << out;
  wire::Envelope ping;
  ping.mutable_ping()->set_nonce(5);
  other_admin->send(ping);
  bool pong = false;
  while (auto m = other_admin->receive(5s)) {
    if ((pong = m->has_pong())) break;
    EXPECT_FALSE(m->has_error()) << m->error().message();
  }
  EXPECT_TRUE(pong);  // and the admins connected stay
}

TEST_F(Bans, ABanWrittenByAnotherProcessTakesEffectOnSighup) {
  test::ServerProcess server(server_args());
  auto alice = join(server.port(), token("alice"));
  store::Ban b = ban(Ban::Kind::kPlayer, "alice");
  b.reason = "from the web panel";
  store::open_ban_store((dir_ / "world").string())->put(b);
  ::kill(server.pid(), SIGHUP);
  const wire::Error told = closed_with(*alice);
  EXPECT_EQ(told.code(), wire::Error::BANNED);
  EXPECT_NE(told.message().find("from the web panel"), std::string::npos) << told.message();
}

}  // namespace
}  // namespace vox

namespace vox {
namespace {

// The same fixture: a voxeld with a key, here also with a --config file.
class Reloading : public Bans {};

TEST_F(Reloading, SighupAppliesNewBudgetsAndANewKeyAndABrokenFileChangesNothing) {
  const std::filesystem::path conf = dir_ / "voxeld.conf";
  std::ofstream(conf) << "edit-budget = 1000\n";
  std::vector<std::string> args = server_args();
  args.insert(args.end(), {"--config", conf.string(), "--log-level", "info"});
  test::ServerProcess server(args);
  const auto budget_of_a_new_player = [&](const std::string& tok) {
    Client c;
    c.connect("127.0.0.1", server.port(), 5s);
    const wire::Envelope w = hello(c, tok);
    return w.has_welcome() ? w.welcome().edit_budget_per_second() : -1.0;
  };
  // As the README says to: a new file renamed over the old one (a reload never reads a
  // file half written).
  const auto write_conf = [&](const std::string& text) {
    std::ofstream(conf.string() + ".new") << text;
    std::filesystem::rename(conf.string() + ".new", conf);
  };
  const auto log_has = [&](const std::string& line) {
    for (int i = 0; i < 200; ++i) {
      std::ifstream log(server.log_path());
      const std::string text((std::istreambuf_iterator<char>(log)), {});
      if (text.find(line) != std::string::npos) return true;
      std::this_thread::sleep_for(20ms);
    }
    return false;
  };
  const auto sighup_and_wait = [&](const std::string& line) {
    ::kill(server.pid(), SIGHUP);
    return log_has(line);
  };
  EXPECT_EQ(budget_of_a_new_player(token("alice")), 1000);
  write_conf("edit-budget = 2500\nmax-view-radius = 5\n");
  ASSERT_TRUE(sighup_and_wait("SIGHUP: edit-budget: 1000 -> 2500"));
  EXPECT_TRUE(log_has("max-view-radius: 12 -> 5 needs a restart (still 12)"));
  EXPECT_EQ(budget_of_a_new_player(token("alice")), 2500);

  write_conf("edit-budget = lots\n");
  ASSERT_TRUE(sighup_and_wait("; nothing changed"));
  EXPECT_EQ(budget_of_a_new_player(token("alice")), 2500);

  // A new key in the same file: old tokens are refused from now on, new ones taken.
  const std::string old_token = token("bob");
  key_ = auth::generate_key_pair();
  std::ofstream(dir_ / "game.pub.new") << auth::key_to_text(key_.public_key);
  std::filesystem::rename(dir_ / "game.pub.new", dir_ / "game.pub");
  write_conf("edit-budget = 2500\nmax-view-radius = 5\n");
  ASSERT_TRUE(sighup_and_wait("(a new key)"));
  Client refused;
  refused.connect("127.0.0.1", server.port(), 5s);
  const wire::Envelope e = hello(refused, old_token);
  ASSERT_TRUE(e.has_error());
  EXPECT_EQ(e.error().code(), wire::Error::BAD_TOKEN);
  EXPECT_EQ(budget_of_a_new_player(token("bob")), 2500);

  // A player already in is held to a reloaded budget too: two of the largest explosions at
  // once (each costs the whole burst), the second waits for what the first
  // took, at the budget's rate: minutes at 2,500 samples a second, a day at 10.
  auto carol = join(server.port(), token("carol"));
  uint64_t request = 0;
  const auto second_of_two_waits_ms = [&] {
    wire::EditResult last;
    for (int i = 0; i < 2; ++i) {
      wire::Envelope m;
      m.mutable_edit()->set_request_id(++request);
      auto* x = m.mutable_edit()->mutable_explosion();
      x->mutable_center()->set_y(500);
      x->set_radius(32), x->set_power(1);
      carol->send(m);
      for (;;) {
        auto r = carol->receive(10s);
        if (!r) return -1;
        if (!r->has_edit_result()) continue;
        last = r->edit_result();
        break;
      }
    }
    return last.status() == wire::EditResult::RATE_LIMITED ? int(last.retry_after_ms()) : 0;
  };
  const int before = second_of_two_waits_ms();
  EXPECT_GT(before, 100'000);
  EXPECT_LT(before, 1'000'000);
  write_conf("edit-budget = 10\nmax-view-radius = 5\n");
  ASSERT_TRUE(sighup_and_wait("SIGHUP: edit-budget: 2500 -> 10"));
  EXPECT_GT(second_of_two_waits_ms(), 3'600'000);  // 10 a second now, for carol as well
}

}  // namespace
}  // namespace vox
