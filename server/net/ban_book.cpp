#include "server/net/ban_book.hpp"

namespace vox::net {

std::optional<store::Ban> BanBook::match(const std::string& player_id, const std::string& address,
                                         int64_t now_ms) const {
  if (!player_id.empty()) {
    const auto it = bans_.find({Ban::Kind::kPlayer, player_id});
    if (it != bans_.end() && !it->second.expired(now_ms)) return it->second;
  }
  const auto it = bans_.find({Ban::Kind::kAddress, address});
  if (it != bans_.end() && !it->second.expired(now_ms)) return it->second;
  return std::nullopt;
}

bool BanBook::put(Ban b) {
  Key key{b.kind, b.target};
  auto it = bans_.find(key);
  if (it != bans_.end()) {
    it->second = std::move(b);
    return true;
  }
  if (bans_.size() >= store::kMaxBans) return false;
  bans_.emplace(std::move(key), std::move(b));
  return true;
}

std::optional<store::Ban> BanBook::remove(Ban::Kind kind, const std::string& target) {
  auto it = bans_.find({kind, target});
  if (it == bans_.end()) return std::nullopt;
  Ban b = std::move(it->second);
  bans_.erase(it);
  return b;
}

std::vector<store::Ban> BanBook::replace(std::vector<Ban> bans, int64_t now_ms) {
  std::map<Key, Ban> next;
  std::vector<Ban> added;
  for (Ban& b : bans) {
    if (b.expired(now_ms) || next.size() >= store::kMaxBans) continue;
    Key key{b.kind, b.target};
    const auto old = bans_.find(key);
    if (old == bans_.end() || old->second.expired(now_ms)) added.push_back(b);
    next.insert_or_assign(std::move(key), std::move(b));
  }
  bans_ = std::move(next);
  return added;
}

void BanBook::drop_ended(int64_t now_ms) {
  std::erase_if(bans_, [now_ms](const auto& entry) { return entry.second.expired(now_ms); });
}

std::string BanBook::cursor_of(const Key& k) {
  return std::string(store::to_string(k.first)) + ":" + k.second;
}

BanBook::Page BanBook::page(const std::string& cursor, size_t max, int64_t now_ms) const {
  Page out;
  auto it = bans_.begin();
  if (!cursor.empty()) {
    // "player:ID" or "address:ADDR": the page starts after it (a cursor naming no ban,
    // or not a cursor at all, starts where that key would sort).
    const size_t colon = cursor.find(':');
    const std::string kind = cursor.substr(0, colon);
    const std::string target = colon == std::string::npos ? "" : cursor.substr(colon + 1);
    const Key key{kind == "player" ? Ban::Kind::kPlayer : Ban::Kind::kAddress, target};
    it = bans_.upper_bound(key);
  }
  for (; it != bans_.end() && out.bans.size() < max; ++it)
    if (!it->second.expired(now_ms)) out.bans.push_back(it->second);
  if (it != bans_.end() && !out.bans.empty())
    out.next = cursor_of({out.bans.back().kind, out.bans.back().target});
  return out;
}

}  // namespace vox::net
